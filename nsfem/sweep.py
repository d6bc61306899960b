"""Parameter sweeps (``nsfem sweep``): one run per value, on a Dask cluster.

``--set KEY=START:STOP:N`` sweeps KEY over N evenly spaced values (several ranges make a
grid, their cartesian product, the first key varying slowest); a plain ``--set KEY=VALUE``
fixes a value for every run. The values are validated (the scene loaded with its overrides)
before anything is computed: every run's for sweeps of at most :data:`CHECK_ALL` runs, else
:data:`CHECKED_VALUES` per key, the other scenes as their runs are submitted (:func:`checked_points`).
At most :data:`MAX_POINTS` runs and :func:`max_workers` local workers, never more workers than runs.

Runs that differ only in keys of :data:`SHARED_TABLES` (speed, damping, initial state,
simulation and output settings) share one assembled model and one reduction basis (but not speeds
when a bearing's coefficients depend on the speed): they are
built once on the client and sent once to every worker (design section 2: speed-dependent
matrices are never reassembled). Every other key (mesh, reduction, shaft, delaminations,
friction and restitution, which the contact set reads from the model's stack) gets its own
model, again once per distinct value, built when its first run is submitted. Runs are submitted
two per worker thread ahead of the finished ones (counted again as workers join), so the first row
comes after one run.

Each run writes ``<out>/<name>/result.npz`` and ``<out>/<name>/record.json`` (its row; the
ledger of resumption, written last and atomically); ``<out>/sweep.csv`` and
``<out>/sweep.json`` are rewritten atomically as runs finish (at most once a second, see
:data:`TABLE_EVERY`) and at the end, ``<out>/resonance.png`` at the end. With sensors, each row holds
their steady 1x amplitude and phase lag, fitted over whole periods of the run's last half
(:func:`sensor_amplitudes`); :func:`table_lines` is the table ``nsfem sweep`` prints.

>>> fixed, axes = parse_ranges(["rotation.speed_hz=10:20:3", "mesh.elements=20"])
>>> fixed, axes
(['mesh.elements=20'], [Axis(key='rotation.speed_hz', values=(10, 15, 20))])
>>> sweep_values(axes + [Axis("damping.external", (0.0, 0.5))])[:3]
[{'rotation.speed_hz': 10, 'damping.external': 0.0}, {'rotation.speed_hz': 10, 'damping.external': 0.5}, \
{'rotation.speed_hz': 15, 'damping.external': 0.0}]
>>> run_name({"rotation.speed_hz": 17.5})
'rotation.speed_hz=17.5'
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import json
import math
import os
import re
import time
import tomllib
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from .atomic import check_folder, write_text_atomic
from .errors import IntegrationError, NsfemError
from .jsonio import as_text, dumps

#: Scene tables that enter neither the assembled model nor its reduction basis (build_model
#: reads the stack and scene.mesh_options, scene_reduction scene.reduction, the contact set
#: friction and restitution from the model's stack): runs differing only here share one model.
SHARED_TABLES = ("title", "rotation", "damping", "initial", "simulation", "output")
#: The run keys of every row (design section 5), then the row's error and results file.
RUN_KEYS = ("method", "t_end", "completed", "wall_s", "ndof_full", "ndof", "events", "impacts", "min_gap_m",
            "max_gap_m", "closed_fraction", "max_normal_force_N", "energy")
#: The most runs one sweep may have (a typo in N should not plan a billion runs): a run takes a
#: second or more, so 10 000 runs are hours on a workstation; more is a typo or a job for a cluster
#: split into several sweeps (each resumable in its own folder)
MAX_POINTS = 10_000
#: The most local worker processes per core: each is a Python process holding the model (a few
#: hundred MB); beyond a few per core they only compete for the cores and the memory (the issue's
#: 1000 workers on 2 cores: 2.7 GB and no run done in 90 s), so a larger --workers is a typo
WORKERS_PER_CORE = 4


def max_workers() -> int:
    """The largest ``--workers``: :data:`WORKERS_PER_CORE` per core of this machine."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_workers(workers: int | None) -> None:
    """Refuse a ``--workers`` below 1 or above :func:`max_workers` (before anything is set up)."""
    if workers is None:
        return
    if workers < 1:
        raise NsfemError(f"--workers must be a positive integer, got {workers}")
    if workers > max_workers():
        raise NsfemError(f"--workers {workers}: more than {WORKERS_PER_CORE} per core ({max_workers()} on the "
                         f"{os.cpu_count() or 1} cores here); more processes only compete for the cores and memory "
                         "(use --scheduler for a larger cluster)")


@dataclass(frozen=True)
class Axis:
    """One swept key and its values."""

    key: str
    values: tuple


def parse_range(key: str, text: str) -> tuple:
    """The values of ``START:STOP:N`` (N evenly spaced, ends included; integers when both ends
    are written as integers and every value is whole).

    >>> parse_range("k", "15:25:5"), parse_range("k", "0.5:0.5:1"), parse_range("k", "1e-3:3e-3:3")
    ((15, 17.5, 20, 22.5, 25), (0.5,), (0.001, 0.002, 0.003))
    """
    parts = [p.strip() for p in text.split(":")]
    head = f"--set {key}=START:STOP:N"
    if len(parts) != 3:
        raise NsfemError(f"{head}: a range has three parts separated by ':', got {text.strip()!r}")
    ends = []
    for name, part in zip(("START", "STOP"), parts):
        try:
            v = float(part)
        except ValueError:
            v = float("nan")
        if not np.isfinite(v):
            raise NsfemError(f"{head}: {name} must be a finite number, got {part!r}")
        ends.append(v)
    start, stop = ends
    if not re.fullmatch(r"\+?\d+", parts[2]) or int(parts[2]) < 1:
        raise NsfemError(f"{head}: N must be a positive integer, got {parts[2]!r}")
    n = int(parts[2])
    if n > MAX_POINTS:
        raise NsfemError(f"{head}: N = {n} exceeds the limit of {MAX_POINTS} runs per sweep (split it into "
                         "several sweeps)")
    if n == 1 and start != stop:
        raise NsfemError(f"{head}: N = 1 needs START = STOP, got {parts[0]} and {parts[1]}")
    vals = [float(f"{v:.12g}") for v in np.linspace(start, stop, n)]
    if len(set(vals)) < n:
        # the runs are deterministic and a run's folder is named by its value (12 digits): repeated
        # values would run the same model again, several at once into one folder
        raise NsfemError(f"{head}: the {n} values from {parts[0]} to {parts[1]} are not distinct at 12 significant "
                         "digits (a run's folder is named by its value); give N = 1 for one value, or a wider range")
    if re.fullmatch(r"[-+]?\d+", parts[0]) and re.fullmatch(r"[-+]?\d+", parts[1]):
        vals = [int(v) if v.is_integer() else v for v in vals]
    return tuple(vals)


def parse_ranges(overrides: Iterable[str]) -> tuple[list[str], list[Axis]]:
    """Split ``--set`` overrides into fixed ones (``KEY=VALUE``) and swept axes (``KEY=START:STOP:N``).

    A value with a ``:`` after a number (``10:``, ``nan:``) is a range; other values (``C:/out``) are not.
    """
    fixed: list[str] = []
    axes: list[Axis] = []
    for o in overrides:
        key, sep, text = o.partition("=")
        if sep and ":" in text and _is_float(text.partition(":")[0]):
            key = key.strip()
            if any(a.key == key for a in axes):
                raise NsfemError(f"{key}: swept twice (give one range per key)")
            axes.append(Axis(key, parse_range(key, text)))
        else:
            fixed.append(o)
    for o in fixed:
        key = o.partition("=")[0].strip()
        if any(a.key == key for a in axes):
            raise NsfemError(f"{key}: both swept and fixed (drop one of its --set)")
    total = int(np.prod([len(a.values) for a in axes], dtype=float)) if axes else 0
    if total > MAX_POINTS:
        raise NsfemError(f"the sweep has {total} runs ({' x '.join(f'{a.key}: {len(a.values)} values' for a in axes)}),"
                         f" more than the limit of {MAX_POINTS} runs per sweep (split it into several sweeps)")
    return fixed, axes


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def sweep_values(axes: Sequence[Axis]) -> list[dict]:
    """The points of the sweep: the cartesian product of the axes, the first varying slowest."""
    return [dict(zip((a.key for a in axes), combo)) for combo in itertools.product(*(a.values for a in axes))]


def run_name(point: dict) -> str:
    """The folder name of a point's run: its assignments, stable when values are added."""
    return ",".join(f"{k}={_num(v)}" for k, v in point.items())


def _num(v) -> str:
    return str(v) if isinstance(v, int) else format(v, ".12g")


def point_overrides(point: dict) -> list[str]:
    return [f"{k}={_num(v)}" for k, v in point.items()]


def fingerprint(base, keys: Sequence[str], method: str, steady: str = "transient") -> str:
    """Hash of what makes two sweeps' runs comparable: the validated scene (every default filled in,
    fixed overrides applied, ``[output]`` and the swept keys left out, the mesh file's bytes), the
    swept keys, the method and the steady state's kind (``steady``: a periodic sweep's rows are orbits, never
    mixed with a transient sweep's). Reordered or no-op ``--set`` flags give the same fingerprint."""
    tree = json.loads(json.dumps(dict(base), default=str))
    tree.pop("output", None)
    for key in keys:
        _drop(tree, key)
    blob = {"scene": tree, "mesh": mesh_digest(base.mesh_file), "keys": list(keys), "method": method}
    if steady != "transient":   # (a transient sweep's fingerprint as before: its folders resume)
        blob["steady"] = steady
    blob = json.dumps(blob, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def mesh_digest(mesh: Path | None) -> str:
    """SHA-256 of a scene's mesh file (empty without one, or if it is gone)."""
    return hashlib.sha256(mesh.read_bytes()).hexdigest() if mesh is not None and mesh.is_file() else ""


def _drop(tree, key: str) -> None:
    """Remove a dotted key (list items by index) from a tree, if there."""
    *path, last = key.split(".")
    node = tree
    try:
        for part in path:
            node = node[int(part)] if isinstance(node, list) else node[part]
        if isinstance(node, dict):
            node.pop(last, None)
        elif isinstance(node, list):
            node[int(last)] = None
    except (KeyError, IndexError, ValueError, TypeError):
        pass


def scene_source(scene_path) -> str:
    from .scene import scene_file

    return scene_file(scene_path).read_text(encoding="utf-8")


# --------------------------------------------------------------------------- one run (on a worker)
def write_json(path: Path, payload: Any) -> Path:
    """Write JSON atomically (temporary file in the same folder, then rename)."""
    return write_text_atomic(path, dumps(payload, as_text, indent=1) + "\n")


def run_point(scene, method: str, shared, run_dir: str, scene_text: str, point: dict, fp: str,
              steady: str = "transient") -> dict:
    """One run of a sweep (a worker's task): integrate, save ``result.npz``, write ``record.json``; with
    ``steady="periodic"`` the periodic orbit instead (:func:`orbit_point`).

    ``shared`` is ``(model, reduction)`` or None (then built here). Any exception becomes the
    row's ``error``; the record is written last, so a run counts as done only once complete.
    """
    if steady == "periodic":
        return orbit_point(scene, shared, run_dir, point, fp)
    from .fem.constraints import dense
    from .simulate import run_scene

    run_dir = Path(run_dir)
    model, red = shared if shared is not None else (None, None)
    warnings: list[str] = []
    row = error_row(point, method, "")
    t0 = time.perf_counter()
    try:
        try:
            result, system = run_scene(scene, method, progress=False, model=model, reduction=red,
                                       warn=warnings.append)
            error = ""
        except IntegrationError as exc:  # keep what was computed
            result, system, error = exc.result, exc.system, str(exc)
        red = system.info["reduction"]
        path = result.save(run_dir / "result.npz", scene_text, dense(red.T), system.model_contacts.x, scene.record())
        summary = result.summary()
        finite = bool(np.all(np.isfinite(result.q)))
        # a broken-off run has no steady state, an overflowed one no amplitudes
        amplitudes = sensor_amplitudes(result, system, warnings.append) if not error and finite else {}
        bad = [k for k, v in {**summary, **amplitudes}.items()
               if isinstance(v, float) and not math.isfinite(v) and k != "energy"]
        if not error and (bad or not finite):
            error = (f"the result is not finite ({', '.join(bad) or 'the displacements'}): the motion overflowed "
                     "the floating-point range")
            amplitudes = {}
        row.update(summary, error=error, result=str(path), outputs=[str(path)],
                   integration_wall_s=summary["wall_s"])
        row.update(amplitudes)
    except Exception as exc:  # noqa: BLE001 - every failure is reported in its row
        row["error"] = _message(exc)
    row["wall_s"] = time.perf_counter() - t0  # as nsfem run: the whole run (the shared model built before)
    row["warnings"] = warnings
    write_json(run_dir / "record.json", {"fingerprint": fp, "point": point, "row": row, "amplitudes": AMPLITUDE_FIT})
    return row


#: the steady states a sweep records: a transient's last half (``nsfem run``) or the periodic orbit
STEADY = ("transient", "periodic")
#: the columns of a periodic sweep besides the run keys (of the orbit's period) and the amplitudes
PERIODIC_KEYS = ("stable", "largest_multiplier", "events_per_period", "converged")
#: What a periodic sweep's amplitudes are (stamped on its records)
AMPLITUDE_FIT_PERIODIC = "1x fit: c + a cos + b sin of the rotation angle over one period of the periodic orbit"


def orbit_point(scene, shared, run_dir: str, point: dict, fp: str) -> dict:
    """One value of ``nsfem sweep --steady periodic`` (a worker's task): the scene's periodic orbit
    (:func:`nsfem.periodic.scene.orbit_of_scene`), saved as ``orbit.npz``; its row holds the run keys of one
    period of the orbit, the sensors' 1x amplitude and phase lag fitted over exactly that period (exact for a
    periodic signal sampled uniformly over its period: the same measure as a transient sweep's, without its
    transient) and :data:`PERIODIC_KEYS`. A shooting that does not converge is a warning of its row (its
    ``converged`` false), an error (refused scene, failed flow) the row's ``error``."""
    from .analysis.harmonic import amplitude_phase, harmonic_fit
    from .periodic.output import save_orbit
    from .periodic.scene import orbit_of_scene

    run_dir = Path(run_dir)
    model, red = shared if shared is not None else (None, None)
    warnings: list[str] = []
    row = {**error_row(point, "exact", ""), **dict.fromkeys(PERIODIC_KEYS)}
    t0 = time.perf_counter()
    try:
        so = orbit_of_scene(scene, warn=warnings.append, model=model, reduction=red)
        o = so.orbit
        path = save_orbit(run_dir / "orbit.npz", so, so.to_json())
        summary = o.result.summary()
        mu = np.abs(np.asarray(o.multipliers, dtype=complex))
        row.update(summary, result=str(path), outputs=[str(path)], integration_wall_s=summary["wall_s"],
                   stable=bool(o.stable) if o.converged else None, largest_multiplier=float(mu.max(initial=0.0)),
                   events_per_period=int(o.events_per_period), converged=bool(o.converged), period_s=so.period_s,
                   loss=o.loss if o.converged else None, residual=float(o.residual))
        if so.sensors:
            f = scene.rotation.speed_hz
            t, y = so.t[:-1], so.signals[:-1]   # one period, its end (the start again) left out
            A, phi = amplitude_phase(harmonic_fit(t, y, f, math.radians(scene.rotation.phase_deg)))
            for k, sensor in enumerate(so.sensors):
                row[AMPLITUDE.format(sensor.name)], row[PHASE.format(sensor.name)] = float(A[k]), float(phi[k])
    except Exception as exc:  # noqa: BLE001 - every failure is reported in its row
        row["error"] = _message(exc)
    row["wall_s"] = time.perf_counter() - t0
    row["warnings"] = warnings
    write_json(run_dir / "record.json", {"fingerprint": fp, "point": point, "row": row,
                                         "amplitudes": AMPLITUDE_FIT_PERIODIC, "steady": "periodic"})
    return row


#: the columns of sensor amplitudes and phases: ``amplitude_<sensor name>_m``, ``phase_<sensor name>_deg``
AMPLITUDE = "amplitude_{}_m"
PHASE = "phase_{}_deg"
#: What the amplitudes are (stamped on each run's record.json: rows of an older definition, half the
#: peak-to-peak, are run again rather than mixed into one table with these)
AMPLITUDE_FIT = "1x fit: c + a cos + b sin of the rotation angle over the last half's whole periods"
#: The share of the run the steady harmonic is fitted over (its last part), and the change of the fitted
#: amplitude between the window's two halves above which a row warns that its run is not steady yet
STEADY_SHARE = 0.5
STEADY_DRIFT = 1e-2
#: The fewest samples a period the fit takes: below, harmonics k = n -+ 1 of n samples a period alias onto 1x
MIN_SAMPLES_PER_PERIOD = 8


def sensor_amplitudes(result, system, warn: Callable[[str], None] = lambda text: None) -> dict:
    """Per sensor of the run, its steady 1x response: amplitude [m] and phase lag [deg] of the harmonic
    at the speed, c + a cos(theta) + b sin(theta) = c + A cos(theta - phi) with theta the rotation angle,
    fitted over the whole periods of the last :data:`STEADY_SHARE` of the run (the resonance curve of a
    rotor). The offset c (the sag) and the other harmonics do not enter A. None for a sensor where the
    fit has nothing to go on (no speed, less than a period, too few samples a period: ``warn`` says
    which); ``warn`` also names sensors whose amplitude still changes by more than :data:`STEADY_DRIFT`."""
    from .analysis.harmonic import steady_harmonic
    from .simulate import sensor_signals

    sensors = system.info.get("sensors", ())
    if not sensors or result.t.size < 2:
        return {}
    empty = {**{AMPLITUDE.format(s.name): None for s in sensors}, **{PHASE.format(s.name): None for s in sensors}}
    f = float(result.info.get("speed_hz", 0.0))
    if f <= 0:
        return empty              # no rotation, no 1x (an unbalance at rest has no force)
    span = result.t[-1] - result.t[0]
    if STEADY_SHARE * span * f < 1:
        warn(f"no sensor amplitudes: the last half of the run ({STEADY_SHARE * span:.4g} s) holds less than one "
             f"period at {f:.6g} Hz ({1 / f:.4g} s); lengthen simulation.t_end")
        return empty
    per_period = 1.0 / (f * float(np.median(np.diff(result.t))))
    if per_period < MIN_SAMPLES_PER_PERIOD:
        warn(f"no sensor amplitudes: {per_period:.3g} samples a period at {f:.6g} Hz (at least "
             f"{MIN_SAMPLES_PER_PERIOD}: higher harmonics alias onto 1x); lower simulation.output_dt")
        return empty
    A, phi, drift = steady_harmonic(result.t, sensor_signals(result, system), f,
                                    np.radians(result.info.get("phase_deg", 0.0)), STEADY_SHARE)
    out = {}
    for k, s in enumerate(sensors):
        out[AMPLITUDE.format(s.name)], out[PHASE.format(s.name)] = float(A[k]), float(phi[k])
        if drift[k] > STEADY_DRIFT:
            warn(f"sensor {s.name}: its 1x amplitude changes by {100 * drift[k]:.2g} % between the halves of the "
                 f"last {STEADY_SHARE * span:.4g} s (not steady yet; lengthen simulation.t_end)")
    return out


def _message(exc: BaseException) -> str:
    text = str(exc) if isinstance(exc, NsfemError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())


def current_amplitudes(rec: dict) -> bool:
    """Whether a run record's sensor amplitudes (if it has any) are of this version's definition
    (:data:`AMPLITUDE_FIT`); an older record's (half the peak-to-peak) would mix two measures in one table."""
    row = rec.get("row")
    return rec.get("amplitudes") in (AMPLITUDE_FIT, AMPLITUDE_FIT_PERIODIC) or not any(str(k).startswith("amplitude_") for k in row or ())


def error_row(point: dict, method: str, error: str) -> dict:
    """A row with no results (yet): the point, every run key None, ``error``."""
    return {**point, **dict.fromkeys(RUN_KEYS), "method": method, "error": error, "result": "", "outputs": [],
            "warnings": []}


def read_record(run_dir: Path, fp: str) -> dict | None:
    """The row of a finished (completed), successful run of this sweep in ``run_dir``, else None."""
    try:
        rec = json.loads((Path(run_dir) / "record.json").read_text())
    except (OSError, ValueError):
        return None
    row = rec.get("row") if isinstance(rec, dict) else None
    if (not isinstance(row, dict) or rec.get("fingerprint") != fp or row.get("error") or not row.get("result")
            or row.get("completed") is not True or not current_amplitudes(rec)):
        return None
    return row if Path(row["result"]).is_file() else None


# --------------------------------------------------------------------------- the sweep (on the client)
#: Seconds to connect to a scheduler and for its first worker to be there; seconds to close a cluster
#: (its workers asked to stop, then killed): closing a local cluster whose workers are busy takes
#: 4 s on a loaded machine; a close cut short at 2 s left the cluster to distributed's own close at
#: exit, which then waited 10 s more (measured: 32 s from SIGTERM to exit, 21 s with 10 s here)
CONNECT_TIMEOUT = 10.0
CLOSE_TIMEOUT = 10.0
#: A worker preload script (run in the worker process's main thread as it starts).
_IGNORE_SIGINT = "import signal; signal.signal(signal.SIGINT, signal.SIG_IGN)"


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM, from the command line) during a sweep: ``result`` holds the finished rows,
    already written to the sweep folder."""

    def __init__(self, result: "SweepResult"):
        super().__init__(f"sweep interrupted; the finished runs are in {result.out_dir}")
        self.result = result


@dataclass
class SweepResult:
    """The rows of the sweep folder in the order of the swept values (``points``, ``runs``): this
    sweep's values and those of earlier sweeps into the same folder with the same fingerprint;
    ``current`` names this invocation's runs, ``info`` says how it went."""

    axes: list[Axis]
    points: list[dict]
    runs: list[dict | None]
    out_dir: Path
    table: Path
    figure: Path | None = None
    info: dict = field(default_factory=dict)
    current: set = field(default_factory=set)
    entries: dict = field(default_factory=dict)
    position: dict = field(default_factory=dict, repr=False)   # run name -> index into points/runs

    def set_row(self, point: dict, row: dict | None) -> None:
        """Enter (or replace) a point's row; ``points``/``runs`` stay sorted by the swept values."""
        self.set_rows([(point, row)])

    def set_rows(self, pairs: Iterable[tuple[dict, dict | None]]) -> None:
        """:meth:`set_row` for many points, sorted once (a sweep of 10 000 points starts at once); a
        row of a point already there takes its place, unsorted (sorting 10 000 points after every
        finished run took 12 ms each: 2 minutes of the client's time over the sweep)."""
        added = False
        for point, row in pairs:
            name = run_name(point)
            if name in self.entries:
                if row is None:
                    continue
                self.entries[name] = (point, row)
                if name in self.position:
                    self.runs[self.position[name]] = row
                    continue
            self.entries[name] = (point, row)
            added = True
        if added:
            keys = [a.key for a in self.axes]
            order = sorted(self.entries.items(), key=lambda e: tuple(e[1][0][k] for k in keys))
            self.points = [e[1][0] for e in order]
            self.runs = [e[1][1] for e in order]
            self.position = {name: k for k, (name, _) in enumerate(order)}

    @property
    def failed(self) -> list[dict]:
        """The failed runs among this invocation's values."""
        return [r for p, r in zip(self.points, self.runs)
                if r is not None and r.get("error") and run_name(p) in self.current]

    def to_json(self) -> dict:
        """``parameter``/``values``: a key and numbers for one axis; lists of keys and of value lists for a grid.
        ``values``/``runs``: every finished row of the folder (unfinished values are left out)."""
        keys = [a.key for a in self.axes]
        done = [(p, r) for p, r in zip(self.points, self.runs) if r is not None]
        if len(keys) == 1:
            parameter, values = keys[0], [p[keys[0]] for p, _ in done]
        else:
            parameter, values = keys, [[p[k] for k in keys] for p, _ in done]
        return {"parameter": parameter, "values": values, "runs": [r for _, r in done], "out": str(self.out_dir),
                "table": str(self.table), "figure": str(self.figure) if self.figure else None,
                "failed": len(self.failed), **self.info}


def sensor_names(runs: Sequence[dict | None]) -> list[str]:
    """The sensors whose amplitudes the rows hold, in the order the rows list them (the scene's)."""
    names = [k[len("amplitude_"):-len("_m")] for r in runs if r for k in r
             if k.startswith("amplitude_") and k.endswith("_m")]
    return list(dict.fromkeys(names))


def table_columns(axes: Sequence[Axis], runs: Sequence[dict | None] = ()) -> list[str]:
    """The swept keys, the run keys, each sensor's amplitude and phase the rows hold, error and result file."""
    sensors = [c for name in sensor_names(runs) for c in (AMPLITUDE.format(name), PHASE.format(name))]
    periodic = list(PERIODIC_KEYS) if any(r and "largest_multiplier" in r for r in runs) else []
    return [a.key for a in axes] + list(RUN_KEYS) + periodic + sensors + ["error", "result"]


def value_digits(values: Iterable) -> int:
    """The significant digits that show ``values`` apart: 6, or more (up to 12, a run folder's) where
    6 would print two of them alike.

    >>> value_digits([10, 13.181818181818, 45]), value_digits([1.0, 1.0000001])
    (6, 8)
    """
    vals = [v for v in values if isinstance(v, (int, float))]
    for d in range(6, 12):
        if len({format(v, f".{d}g") for v in vals}) == len(set(vals)):
            return d
    return 12


def _cell(v, digits: int = 6) -> str:
    """A table cell: a number to ``digits`` significant digits, "-" for none or not finite, text on one line."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return format(v, f".{digits}g")
    return " ".join(str(v).split()) or "-"


def table_lines(keys: Sequence[str], runs: Sequence[dict | None]) -> list[str]:
    """The sweep's table as ``nsfem sweep`` prints it: per finished value, the contact measures (only when
    the scene has contacts) and each sensor's steady 1x amplitude and phase, numbers to 6 significant
    digits (more where a swept key's values need them to differ), columns aligned.

    >>> print("\\n".join(table_lines(["s"], [{"s": 10, "min_gap_m": None, "amplitude_a_m": 4.222581e-6,
    ...                                          "phase_a_deg": 12.0, "error": ""}])))
    sensors: steady 1x amplitude [m], lag [deg]: a cos + b sin at the speed, fitted over whole periods of each run's last half
      s   a [m]        a [deg]
      10  4.22258e-06  12.0
    """
    shown = [r for r in runs if r is not None]
    contacts = any(not r.get("error") and r.get("min_gap_m") is not None for r in shown)
    sensors = sensor_names(shown)
    digits = {k: value_digits(r.get(k) for r in shown) for k in keys}
    head = list(keys)
    periodic = any("largest_multiplier" in r for r in shown)
    if periodic:
        head += ["stable", "max |mu|", "events/period"]
    if contacts:
        head += ["events", "impacts", "closed [%]", "min gap [m]", "max gap [m]", "max force [N]"]
    for name in sensors:
        head += [f"{name} [m]", f"{name} [deg]"]
    rows = []
    for r in shown:
        cells = [_cell(r.get(k), digits[k]) for k in keys]
        if r.get("error"):
            rows.append((cells, f"failed: {' '.join(str(r['error']).split())}"))
            continue
        if periodic:
            stable = r.get("stable")
            cells += ["-" if stable is None else ("yes" if stable else "NO")
                      + ("" if r.get("converged", True) else " (not converged)"),
                      _cell(r.get("largest_multiplier")), _cell(r.get("events_per_period"))]
        if contacts:
            closed = r.get("closed_fraction")
            cells += [_cell(r.get("events")), _cell(r.get("impacts")), _cell(None if closed is None else 100 * closed, 4),
                      _cell(r.get("min_gap_m"), 5), _cell(r.get("max_gap_m"), 5), _cell(r.get("max_normal_force_N"), 5)]
        for name in sensors:
            phase = r.get(PHASE.format(name))
            cells += [_cell(r.get(AMPLITUDE.format(name))),
                      f"{phase:.1f}" if isinstance(phase, float) and math.isfinite(phase) else _cell(phase)]
        rows.append((cells, ""))
    widths = [max([len(h)] + [len(c[i]) for c, _ in rows if i < len(c)]) for i, h in enumerate(head)]

    def line(cells: Sequence[str], tail: str = "") -> str:
        return "  " + "  ".join([c.ljust(w) for c, w in zip(cells, widths)] + ([tail] if tail else [])).rstrip()

    lines = []
    if sensors and periodic:
        lines.append("sensors: steady 1x amplitude [m], lag [deg]: a cos + b sin at the speed, fitted over one "
                     "period of each periodic orbit")
    elif sensors:
        lines.append("sensors: steady 1x amplitude [m], lag [deg]: a cos + b sin at the speed, fitted over whole "
                     "periods of each run's last half")
    elif not contacts:
        lines.append("no contacts and no [[sensor]]: add sensors to the scene for its response amplitudes")
    lines.append(line(head))
    lines += [line(c, tail) for c, tail in rows]
    return lines


def write_table(path: Path, axes: Sequence[Axis], runs: Sequence[dict | None]) -> Path:
    """The CSV of the finished rows (atomically); unfinished points are left out. An empty cell is a
    value that is not there or not finite (``null`` in the JSON), whether the row was computed now or
    read back from its record.json."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=table_columns(axes, runs), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows({k: ("" if v is None or (isinstance(v, float) and not math.isfinite(v)) else v) for k, v in r.items()}
                for r in runs if r is not None)
    return write_text_atomic(path, buf.getvalue())


def folder_rows(out: Path, fp: str, keys: Sequence[str]) -> list[tuple[dict, dict]]:
    """(point, row) of every run record in ``out`` written by a sweep with fingerprint ``fp``."""
    found = []
    for path in sorted(Path(out).glob("*/record.json")):
        try:
            rec = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(rec, dict) or rec.get("fingerprint") != fp:
            continue
        point, row = rec.get("point"), rec.get("row")
        if isinstance(point, dict) and list(point) == list(keys) and isinstance(row, dict) and current_amplitudes(rec):
            found.append((point, row))
    return found


def format_progress(k: int, n: int, row: dict, keys: Sequence[str], digits: dict | None = None) -> str:
    """``[k/n] rotation.speed_hz=21: exact, 17 events, closed 3.1 %, 0.25 s`` (or the error); the contact
    measures with contacts, each sensor's 1x amplitude with sensors; swept values to ``digits`` {key: d}
    significant digits (6 by default).

    >>> format_progress(1, 5, {"s": 21, "method": "exact", "events": 17, "closed_fraction": 0.031, "min_gap_m": 0.0,
    ...                        "wall_s": 0.25, "error": ""}, ["s"])
    '[1/5] s=21: exact, 17 events, closed 3.1 %, 0.25 s'
    >>> format_progress(2, 5, {"s": 13.181818181818, "method": "exact", "events": 0, "closed_fraction": 0.0,
    ...                        "min_gap_m": None, "amplitude_disk_y_m": 8.530532e-06, "wall_s": 0.44, "error": ""},
    ...                 ["s"])
    '[2/5] s=13.1818: exact, 1x disk_y 8.531e-06 m, 0.44 s'
    """
    head = f"[{k}/{n}] " + ", ".join(f"{key}={_cell(row[key], (digits or {}).get(key, 6))}" for key in keys)
    if row.get("error"):
        return f"{head}: failed: {row['error']}"
    parts = [str(row["method"])]
    if row.get("stable") is not None:   # a periodic orbit's
        parts.append(("stable" if row["stable"] else "unstable") + f" (max |mu| {row['largest_multiplier']:.4g})"
                     + ("" if row.get("converged", True) else ", NOT converged"))
    if row.get("min_gap_m") is not None:
        parts += [f"{row['events']} events", f"closed {100 * row['closed_fraction']:.1f} %"]
    amplitudes = [f"{name} {_cell(row.get(AMPLITUDE.format(name)), 4)} m" for name in sensor_names([row])]
    if amplitudes:
        parts.append("1x " + ", ".join(amplitudes))
    return f"{head}: {', '.join(parts)}, {row['wall_s']:.2f} s"


#: The table and JSON are rewritten as runs finish, at most once per TABLE_EVERY seconds and after at
#: least TABLE_SHARE times the last rewrite's duration (10 000 rows take 1.1 s to write: rewritten
#: after every run, a sweep's writing grows with the square of its runs); always at the end or on
#: Ctrl-C. Each run's record.json, the ledger a rerun resumes from, is written as the run ends.
TABLE_EVERY = 1.0
TABLE_SHARE = 10.0
#: Sweeps of at most this many runs load every run's scene before anything runs (6 ms each for
#: the crack scene: 1.5 s); larger ones load each key's values (at most CHECKED_VALUES of them, evenly
#: spaced, the ends included) before, and every run's scene as it is submitted (a combination the
#: scene refuses then fails its row): 90 000 scenes took 9 minutes before the first run
CHECK_ALL = 256
CHECKED_VALUES = 64
#: Runs kept submitted per worker thread of the cluster (the next one waits on its worker, so none
#: idles between runs), and the seconds between looks at the cluster's threads: workers started with
#: ``dask worker`` may join a scheduler after the sweep began (it waits for the first only)
AHEAD = 2
THREADS_EVERY = 1.0


@dataclass
class _Plan:
    points: list[dict]
    fixed: list[str]
    axes: list[Axis]
    method: str
    scene_text: str
    fp: str
    base: Any = None
    scene_path: Any = None
    scenes: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)
    steady: str = "transient"

    def scene(self, i: int):
        """The scene of point ``i`` (loaded now unless checked before; NsfemError when refused)."""
        if i in self.scenes:
            return self.scenes.pop(i)
        return self.load(self.points[i])

    def load(self, point: dict):
        """The scene at ``point`` from the scene file's text as the sweep read it when it began (the
        file edited during a sweep of hours must not change its later runs, as the fingerprint and
        every run's stored text are of that text)."""
        from .scene import scene_from_tree

        return scene_from_tree(self.raw, self.fixed + point_overrides(point), path=self.base.path, base=self.base.base)

    def model_group(self, i: int) -> tuple:
        """What identifies point ``i``'s model: its values of the keys outside :data:`SHARED_TABLES`
        (the fixed overrides are the same for every point), and its speed when a bearing's coefficients depend
        on it (the model's K holds the bearings at the scene's speed)."""
        tabled = self.base.stack.speed_dependent
        return tuple(v for k, v in self.points[i].items()
                     if k.split(".")[0] not in SHARED_TABLES or (tabled and k == "rotation.speed_hz"))


def checked_points(axes: Sequence[Axis]) -> list[dict]:
    """The points whose scenes are loaded before any run: every point of a sweep of at most
    :data:`CHECK_ALL` runs, else, per key, at most :data:`CHECKED_VALUES` of its values (evenly spaced,
    the ends included) with the other keys at their first value.

    >>> len(checked_points([Axis("a", tuple(range(300))), Axis("b", (0, 1))])), len(checked_points([Axis("a", (1, 2))]))
    (65, 2)
    """
    points = sweep_values(axes)
    if len(points) <= CHECK_ALL:
        return points
    first = {a.key: a.values[0] for a in axes}
    out = []
    for a in axes:
        picks = np.unique(np.linspace(0, len(a.values) - 1, min(len(a.values), CHECKED_VALUES)).round().astype(int))
        out += [{**first, a.key: a.values[k]} for k in picks if a.values[k] != first[a.key] or not out]
    return out


def check_steady(steady: str, method: str | None) -> None:
    """Refuse an unknown ``--steady`` and a ``--method`` other than exact with ``--steady periodic`` (the orbit
    is shot on the exact flow)."""
    if steady not in STEADY:
        raise NsfemError(f"--steady must be one of {', '.join(STEADY)}, got {steady!r}")
    if steady == "periodic" and method not in (None, "exact"):
        raise NsfemError(f"--method {method} with --steady periodic: the periodic orbit is shot on the exact flow "
                         "(its monodromy matrix is the exact one's); leave --method out")


def plan(scene_path, overrides: Sequence[str], method: str | None = None, steady: str = "transient") -> _Plan:
    """Validate everything (ranges, the scene with its fixed overrides, the points of
    :func:`checked_points`) before any run; the other scenes are loaded as their runs are submitted.
    ``steady="periodic"``: each value's periodic orbit instead of a run (:func:`orbit_point`): every checked
    scene must have one (a constant speed > 0)."""
    check_steady(steady, method)
    from .scene import METHODS, load_scene
    from .scene.overrides import missing_item

    fixed, axes = parse_ranges(overrides)
    base = load_scene(scene_path, fixed)
    for a in axes:
        item = missing_item(base, a.key)
        if item is not None:
            raise NsfemError(f"--set {a.key}=START:STOP:N: the scene has no {item} (sweep keys of items the scene "
                             "has; add the item to the scene, or with a fixed --set)")
    if not axes:
        raise NsfemError("nsfem sweep: nothing to sweep; give at least one --set KEY=START:STOP:N")
    if method is not None and method not in METHODS:
        raise NsfemError(f"simulation.method {method!r} is not available (use {' | '.join(METHODS)})")
    points = sweep_values(axes)
    method = "exact" if steady == "periodic" else method or base.simulation.method
    if any(a.key == "simulation.method" for a in axes):  # pragma: no cover - ranges are numbers
        raise NsfemError("simulation.method cannot be swept")
    keys = [a.key for a in axes]
    text = scene_source(scene_path)
    p = _Plan(points, fixed, axes, method, text, fingerprint(base, keys, method, steady), base, scene_path,
              raw=tomllib.loads(text), steady=steady)
    index = {run_name(pt): i for i, pt in enumerate(points)}
    p.scenes = {index[run_name(pt)]: p.load(pt) for pt in checked_points(axes)}
    if steady == "periodic":
        from .periodic.scene import check_scene

        for i, sc in p.scenes.items():
            try:
                check_scene(sc)
            except NsfemError as exc:
                raise NsfemError(f"--steady periodic at {run_name(points[i])}: {exc}") from None
    return p


def default_folder(p: _Plan) -> Path:
    """``<output.dir>/sweep-<swept keys>``: sweeps of other keys get other folders."""
    return p.base.output.dir / ("sweep-" + ",".join(a.key for a in p.axes))


def _check_folder(out: Path, p: _Plan, scene_path, write: bool = False) -> None:
    """Refuse a folder that holds another sweep (other scene, fixed settings, swept keys or method);
    ``write``: stamp the folder as this sweep's."""
    stamp = out / "sweep-id.json"
    if stamp.is_file():
        try:
            theirs = json.loads(stamp.read_text())
        except ValueError:
            theirs = {}
        if not isinstance(theirs, dict) or theirs.get("fingerprint") != p.fp:
            theirs = theirs if isinstance(theirs, dict) else {}
            raise NsfemError(f"{out} holds another sweep (scene {theirs.get('scene')}, fixed {theirs.get('fixed')}, "
                             f"swept {theirs.get('keys')}, method {theirs.get('method')}, steady "
                             f"{theirs.get('steady', 'transient')}); its results would mix "
                             "with this one's: choose another --out or remove that folder")
    elif write:
        write_json(stamp, {"fingerprint": p.fp, "scene": str(scene_path or "(shipped scene)"), "fixed": p.fixed,
                           "keys": [a.key for a in p.axes], "method": p.method, "steady": p.steady})


def local_workers(workers: int | None, n_runs: int) -> int:
    """The worker processes of a local cluster for ``n_runs`` runs at a time: ``workers`` (checked by
    :func:`check_workers`; default one per core), never more than the runs (the others would idle).

    >>> local_workers(8, 2), local_workers(1, 5), local_workers(None, 1)
    (2, 1, 1)
    """
    check_workers(workers)
    return max(1, min(workers or os.cpu_count() or 1, n_runs))


def _client(client, workers: int | None, scheduler: str | None, n_runs: int):
    """(client, things to close): the given client, one connected to ``scheduler``, or a LocalCluster
    of :func:`local_workers` processes. Any failure to connect, or a cluster without workers, is a
    one-line NsfemError."""
    import logging
    import threading

    from distributed import Client, LocalCluster

    if client is not None:
        c, closing, where = client, [], "the client's cluster"
    elif scheduler:
        # in a thread, bounded: an endpoint that accepts the connection but never answers the
        # handshake (not a Dask scheduler) would otherwise hang the client
        box: dict = {}

        def connect():
            try:
                box["client"] = Client(scheduler, timeout=f"{CONNECT_TIMEOUT}s")
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                box["error"] = exc

        thread = threading.Thread(target=connect, daemon=True, name="nsfem-connect")
        thread.start()
        thread.join(CONNECT_TIMEOUT + 2.0)
        if "client" not in box:
            exc = box.get("error")
            why = _message(exc)[:200] if exc is not None else f"no answer within {CONNECT_TIMEOUT:g} s"
            raise NsfemError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({why})")
        c = box["client"]
        closing, where = [c], f"--scheduler {scheduler}"
    else:
        n = local_workers(workers, n_runs)
        env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        # the workers ignore SIGINT: Ctrl-C in the terminal (sent to the whole process group)
        # reaches only this process, which cancels the runs and closes the cluster, quietly
        # Ctrl-C or SIGTERM while the cluster starts is held until it is there: an exception out of
        # its constructor would leave worker processes that no one closes (and distributed's own
        # close at exit fails on them with a traceback)
        # close, too, what exists when a signal comes as the handlers are restored, before the caller
        # holds ``closing``
        closing, where = [], "the local cluster"
        try:
            with _deferred_signals() as received:
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=logging.ERROR, env=env, preload=[_IGNORE_SIGINT])
                closing = [cluster]
                c = Client(cluster)
                closing = [c, cluster]
            if received:
                raise KeyboardInterrupt
        except BaseException:
            held = _hold_signals()      # a second Ctrl-C must not cut the closing short
            try:
                _close(closing)
            finally:
                _release_signals(held)
            raise
    try:
        c.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
    except KeyboardInterrupt:
        _close(closing)
        raise
    except Exception:  # noqa: BLE001 - a TimeoutError, or the scheduler went away
        _close(closing)
        raise NsfemError(f"{where}: no worker within {CONNECT_TIMEOUT:g} s (start workers with "
                         f"`dask worker {scheduler or 'ADDRESS'}`)") from None
    return c, closing


def _close(closing) -> None:
    """Close clients and clusters promptly, without the log lines of workers lost on the way."""
    import logging

    names = ["distributed"] + [n for n in logging.root.manager.loggerDict if n.startswith("distributed.")]
    levels = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    try:
        for c in closing:
            try:
                c.close(timeout=CLOSE_TIMEOUT)
            except Exception:  # noqa: BLE001 - closing is best effort
                pass
    finally:
        for n, level in levels.items():
            logging.getLogger(n).setLevel(level)


@contextlib.contextmanager
def _deferred_signals():
    """Within the block, SIGINT and SIGTERM are recorded (in the list yielded), not acted on; the
    handlers before are restored after it (main thread only; elsewhere nothing changes). A signal the
    process ignores (SIGINT of a job started in the background by a shell) stays ignored."""
    import signal
    import threading

    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    held = {sig: signal.signal(sig, lambda signum, frame: received.append(signum))
            for sig in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(sig) is not signal.SIG_IGN}
    try:
        yield received
    finally:
        _release_signals(held)


def _hold_signals() -> dict:
    """Ignore SIGINT and SIGTERM (main thread only); returns what to restore."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}


def _release_signals(held: dict) -> None:
    import signal

    for sig, handler in held.items():
        signal.signal(sig, handler)


def run_sweep(scene_path, overrides: Sequence[str], out_dir=None, method: str | None = None, client=None,
              workers: int | None = None, scheduler: str | None = None,
              progress: Callable[[str], None] | None = None, plot: bool = True,
              steady: str = "transient") -> SweepResult:
    """Run a sweep; returns the rows of its folder in the order of the swept values with ``info``.

    ``client``: a ``distributed.Client`` to use; else ``scheduler`` (an address) or a
    LocalCluster of ``workers`` processes (default: one per core, at most one per run), one
    thread each. ``out_dir`` defaults to ``<output.dir>/sweep-<swept keys>``. Runs already done in
    ``out_dir`` by the same sweep are not run again; failed ones are. ``progress(line)``
    receives one line per finished run (and one per warning of it). A model that cannot be
    built fails the rows of its values only. Ctrl-C cancels the pending runs, writes the table
    of the finished ones and raises :class:`SweepInterrupted` (a KeyboardInterrupt) carrying
    them. ``info``: ``executed``, ``resumed``, ``models_built``, ``workers``, ``wall_s``
    (and ``interrupted``). ``steady``: "transient" (each value's run, its last half's 1x amplitudes) or
    "periodic" (each value's periodic orbit, :func:`orbit_point`).
    """
    if workers is not None and (scheduler or client is not None):
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")
    check_workers(workers)
    t0 = time.perf_counter()
    p = plan(scene_path, overrides, method, steady)
    # absolute: the workers (maybe started elsewhere) write there
    out = (Path(out_dir) if out_dir is not None else default_folder(p)).absolute()
    check_folder(out, "--out")  # tried, then left as it was: root passes permission bits everywhere
    _check_folder(out, p, scene_path)
    from .outdir import claim, remove_leftovers

    with claim(out, "sweep"):  # one sweep at a time in the folder; files cut short by a kill removed
        for pt in p.points:
            remove_leftovers(out / run_name(pt))
        return _run_sweep(p, out, scene_path, client, workers, scheduler, progress, plot, t0)


def _run_sweep(p: _Plan, out: Path, scene_path, client, workers: int | None, scheduler: str | None,
               progress: Callable[[str], None] | None, plot: bool, t0: float) -> SweepResult:
    """:func:`run_sweep` in its claimed folder ``out``."""
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    keys = [a.key for a in p.axes]
    done_rows = [read_record(out / run_name(pt), p.fp) for pt in p.points]
    todo = [i for i, r in enumerate(done_rows) if r is None]
    resumed = len(p.points) - len(todo)
    res = SweepResult(p.axes, [], [], out, out / "sweep.csv", current={run_name(pt) for pt in p.points},
                      info={"executed": 0, "resumed": resumed, "models_built": 0, "workers": 0, "wall_s": 0.0,
                            "steady": p.steady})
    res.set_rows(folder_rows(out, p.fp, keys))  # earlier sweeps into this folder, this one's resumed runs
    res.set_rows((pt, None) for pt in p.points)
    say = progress or (lambda line: None)

    written = {"at": -math.inf, "took": 0.0}
    digits = {a.key: value_digits(a.values) for a in p.axes}

    def record(i: int, row: dict) -> None:
        res.set_row(p.points[i], row)
        start = time.perf_counter()
        if start - written["at"] >= max(TABLE_EVERY, TABLE_SHARE * written["took"]):
            write_table(res.table, p.axes, res.runs)
            write_json(out / "sweep.json", res.to_json())
            written["at"] = time.perf_counter()
            written["took"] = written["at"] - start
        res.info["executed"] += 1
        say(format_progress(resumed + res.info["executed"], len(p.points), row, keys, digits))
        for w in row.get("warnings") or []:
            say(f"  warning: {w}")

    def finish() -> SweepResult:
        res.info["wall_s"] = time.perf_counter() - t0
        write_table(res.table, p.axes, res.runs)
        if plot and any(r is not None and not r.get("error") for r in res.runs):
            from .plot.sweep import plot_resonance

            res.figure = plot_resonance(out / "resonance.png", keys, res.points, res.runs, p.base.title)
        write_json(out / "sweep.json", res.to_json())
        return res

    if not todo:
        if resumed:
            say(f"{resumed} of {len(p.points)} runs already done in {out}")
        return finish()
    line = (f"{len(todo)} runs to do ({', '.join(f'{a.key}: {len(a.values)} values' for a in p.axes)}"
            + (f"; {resumed} already done" if resumed else "") + f") into {out}")
    local = client is None and not scheduler
    if local:  # at once, before the seconds a local cluster takes to start
        say(line)
    cl, closing, futures = None, [], {}
    try:
        cl, closing = _client(client, workers, scheduler, len(todo))
        if not local:  # once connected: a scheduler that cannot be reached is one line
            say(line)
        res.info["workers"] = len(cl.nthreads())
        if workers is not None and res.info["workers"] < workers:
            say(f"note: --workers {workers} for {len(todo)} runs: {res.info['workers']} started (one per run)")
        _check_folder(out, p, scene_path, write=True)
        from distributed import as_completed

        # one model and reduction per group of points (their values of the keys outside SHARED_TABLES),
        # built here once, when its first run is submitted; a failed build fails its rows only. The
        # scenes are loaded and the runs submitted as others finish, a few per worker ahead: the first
        # row arrives after one run, however many follow
        rank = {g: k for k, g in enumerate(dict.fromkeys(p.model_group(i) for i in todo))}
        order = sorted(todo, key=lambda i: rank[p.model_group(i)])     # stable: each group in sweep order
        left = dict.fromkeys(rank, 0)
        for i in order:
            left[p.model_group(i)] += 1
        models: dict[tuple, Any] = {}          # group -> scattered (model, reduction), or the build's error
        queue = iter(order)
        slots = {"at": -math.inf, "n": AHEAD}

        def window() -> int:
            """Runs to keep submitted: AHEAD per worker thread the cluster has now."""
            now = time.perf_counter()
            if now - slots["at"] >= THREADS_EVERY:
                with contextlib.suppress(Exception):     # the scheduler busy or going: the last count
                    slots["n"] = AHEAD * max(1, sum(cl.nthreads().values()))
                slots["at"] = now
            return slots["n"]

        def fail(i: int, error: str) -> None:
            row = error_row(p.points[i], p.method, error)
            write_json(out / run_name(p.points[i]) / "record.json", {"fingerprint": p.fp, "point": p.points[i],
                                                                       "row": row})
            record(i, row)

        mesh = mesh_digest(p.base.mesh_file)

        def shared_model(group: tuple, scene):
            if group not in models and mesh_digest(scene.mesh_file) != mesh:
                # models are built as their first run is submitted: one built from a mesh edited since
                # the sweep began would mix two meshes under the first one's fingerprint
                models[group] = (f"the mesh file {scene.mesh_file} has changed since the sweep began (its runs "
                                 "would mix two meshes; sweep into another --out)")
            if group not in models:
                try:
                    model = build_model(scene)
                    built = (model, scene_reduction(scene.reduction, model))
                except Exception as exc:  # noqa: BLE001 - reported in the rows of this model's values
                    models[group] = f"model build failed: {_message(exc)}"
                else:
                    res.info["models_built"] += 1
                    [models[group]] = cl.scatter([built], broadcast=True, hash=False)
            return models[group]

        def submit_next() -> bool:
            """Submit the next run (its scene and model made now); False when none is left."""
            for i in queue:
                group = p.model_group(i)
                left[group] -= 1
                try:
                    scene = p.scene(i)
                except NsfemError as exc:
                    shared = f"scene refused: {_message(exc)}"
                else:
                    shared = shared_model(group, scene)
                if not left[group]:
                    models.pop(group, None)        # its runs hold the model now; the workers free it after them
                if isinstance(shared, str):
                    fail(i, shared)
                    continue
                # a fresh key: the scheduler must never hand back a finished task of an earlier sweep
                fut = cl.submit(run_point, scene, p.method, shared, str(out / run_name(p.points[i])),
                                p.scene_text + "\n# overrides: " + " ".join(p.fixed + point_overrides(p.points[i])),
                                p.points[i], p.fp, p.steady, key=f"nsfem-run-{uuid.uuid4().hex}", pure=False)
                futures[fut] = i
                running.add(fut)
                return True
            return False

        running = as_completed([], loop=cl.loop)
        in_flight = [0]

        def top_up() -> None:
            while in_flight[0] < window() and submit_next():
                in_flight[0] += 1

        top_up()
        for fut in running:
            in_flight[0] -= 1
            i = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker, an unpicklable result
                row = error_row(p.points[i], p.method, _message(exc))
            record(i, row)
            top_up()
    except KeyboardInterrupt:
        held = _hold_signals()  # a second Ctrl-C must not cut the writing of the finished rows short
        if cl is not None:
            try:
                cl.cancel([f for f in futures if not f.done()])
            except Exception:  # noqa: BLE001 - the cluster may be going away too
                pass
        _close(closing)
        closing = []
        res.info["interrupted"] = True
        try:
            finish()
        finally:
            _release_signals(held)
        raise SweepInterrupted(res) from None
    except Exception:
        # the sweep stops (the cluster lost, the folder taken): the table and JSON, rewritten at most
        # once a second, get the rows finished since, as on Ctrl-C (nothing is written before the
        # first); the error goes on up
        if res.info["executed"]:
            with contextlib.suppress(Exception):
                write_table(res.table, p.axes, res.runs)
                write_json(out / "sweep.json", res.to_json())
        raise
    finally:
        _close(closing)
    return finish()
