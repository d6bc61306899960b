"""Parameter sweeps (``nsfem sweep``): one run per value, on a Dask cluster.

``--set KEY=START:STOP:N`` sweeps KEY over N evenly spaced values (several ranges make a
grid, their cartesian product, the first key varying slowest); a plain ``--set KEY=VALUE``
fixes a value for every run. Every value is validated (the scene loaded with its overrides)
before anything is computed.

Runs that differ only in keys of :data:`SHARED_TABLES` (speed, damping, initial state,
simulation and output settings) share one assembled model and one reduction basis: they are
built once on the client and sent once to every worker (design section 2: speed-dependent
matrices are never reassembled). Every other key (mesh, reduction, shaft, delaminations,
friction and restitution, which the contact set reads from the model's stack) gets its own
model, again once per distinct value.

Each run writes ``<out>/<name>/result.npz`` and ``<out>/<name>/record.json`` (its row; the
ledger of resumption, written last and atomically); ``<out>/sweep.csv`` and
``<out>/sweep.json`` are rewritten atomically after every finished run, ``<out>/resonance.png``
at the end.

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

import csv
import hashlib
import io
import itertools
import json
import os
import re
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from .errors import IntegrationError, NsfemError

#: Scene tables that enter neither the assembled model nor its reduction basis (build_model
#: reads the stack and [mesh], scene_reduction reads [reduction], the contact set reads
#: friction and restitution from the model's stack): runs differing only here share one model.
SHARED_TABLES = ("title", "rotation", "damping", "initial", "simulation", "output")
#: The run keys of every row (design section 5), then the row's error and results file.
RUN_KEYS = ("method", "t_end", "completed", "wall_s", "ndof_full", "ndof", "events", "impacts", "min_gap_m",
            "max_gap_m", "closed_fraction", "max_normal_force_N", "energy")
#: The most runs one sweep may have (a typo in N should not plan a billion runs).
MAX_POINTS = 100_000


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
        raise NsfemError(f"{head}: N = {n} exceeds the limit of {MAX_POINTS} runs per sweep")
    if n == 1 and start != stop:
        raise NsfemError(f"{head}: N = 1 needs START = STOP, got {parts[0]} and {parts[1]}")
    vals = [float(f"{v:.12g}") for v in np.linspace(start, stop, n)]
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
        raise NsfemError(f"the sweep has {total} runs, more than the limit of {MAX_POINTS}")
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


def model_key(scene) -> str:
    """What identifies a scene's model and reduction: everything outside :data:`SHARED_TABLES`."""
    tree = {k: v for k, v in scene.items() if k not in SHARED_TABLES}
    return json.dumps([tree, str(scene.mesh_file or "")], sort_keys=True, default=str)


def fingerprint(scene_text: str, fixed: Sequence[str], keys: Sequence[str], method: str) -> str:
    """Hash of what makes two sweeps' runs comparable: scene text, fixed overrides, swept keys, method."""
    blob = json.dumps({"scene": scene_text, "fixed": list(fixed), "keys": list(keys), "method": method})
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def scene_source(scene_path) -> str:
    from .scene import default_scene_path

    p = Path(scene_path) if scene_path is not None else default_scene_path()
    return p.read_text(encoding="utf-8")


# --------------------------------------------------------------------------- one run (on a worker)
def write_json(path: Path, payload: Any) -> Path:
    """Write JSON atomically (temporary file in the same folder, then rename)."""
    return _atomic_text(Path(path), json.dumps(payload, indent=1, default=_default) + "\n")


def _atomic_text(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def run_point(scene, method: str, shared, run_dir: str, scene_text: str, point: dict, fp: str) -> dict:
    """One run of a sweep (a worker's task): integrate, save ``result.npz``, write ``record.json``.

    ``shared`` is ``(model, reduction)`` or None (then built here). Any exception becomes the
    row's ``error``; the record is written last, so a run counts as done only once complete.
    """
    from .fem.constraints import dense
    from .simulate import run_scene

    run_dir = Path(run_dir)
    model, red = shared if shared is not None else (None, None)
    warnings: list[str] = []
    row: dict = {**point, **dict.fromkeys(RUN_KEYS), "method": method, "error": "", "result": ""}
    t0 = time.perf_counter()
    try:
        try:
            result, system = run_scene(scene, method, progress=False, model=model, reduction=red,
                                       warn=warnings.append)
            error = ""
        except IntegrationError as exc:  # keep what was computed
            result, system, error = exc.result, exc.system, str(exc)
        red = system.info["reduction"]
        path = result.save(run_dir / "result.npz", scene_text, dense(red.T), system.contacts.x, dict(scene))
        row.update(result.summary(), error=error, result=str(path))
    except Exception as exc:  # noqa: BLE001 - every failure is reported in its row
        row["error"] = f"{type(exc).__name__}: {exc}" if not isinstance(exc, NsfemError) else str(exc)
    row["run_wall_s"] = time.perf_counter() - t0
    row["warnings"] = warnings
    write_json(run_dir / "record.json", {"fingerprint": fp, "point": point, "row": row})
    return row


def read_record(run_dir: Path, fp: str) -> dict | None:
    """The row of a finished, successful run of this sweep in ``run_dir``, else None."""
    try:
        rec = json.loads((Path(run_dir) / "record.json").read_text())
    except (OSError, ValueError):
        return None
    row = rec.get("row") if isinstance(rec, dict) else None
    if rec.get("fingerprint") != fp or not isinstance(row, dict) or row.get("error") or not row.get("result"):
        return None
    return row if Path(row["result"]).is_file() else None


# --------------------------------------------------------------------------- the sweep (on the client)
@dataclass
class SweepResult:
    """The rows of a sweep in its order (``runs``), where they are, and how it went (``info``)."""

    axes: list[Axis]
    points: list[dict]
    runs: list[dict | None]
    out_dir: Path
    table: Path
    figure: Path | None = None
    info: dict = field(default_factory=dict)

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.runs if r is not None and r.get("error")]

    def to_json(self) -> dict:
        """``parameter``/``values``: a key and numbers for one axis; lists of keys and of value lists for a grid."""
        keys = [a.key for a in self.axes]
        if len(keys) == 1:
            parameter, values = keys[0], [p[keys[0]] for p in self.points]
        else:
            parameter, values = keys, [[p[k] for k in keys] for p in self.points]
        return {"parameter": parameter, "values": values, "runs": self.runs, "out": str(self.out_dir),
                "table": str(self.table), "figure": str(self.figure) if self.figure else None,
                "failed": len(self.failed), **self.info}


def table_columns(axes: Sequence[Axis]) -> list[str]:
    return [a.key for a in axes] + list(RUN_KEYS) + ["error", "result"]


def write_table(path: Path, axes: Sequence[Axis], runs: Sequence[dict | None]) -> Path:
    """The CSV of the finished rows (atomically); unfinished points are left out."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=table_columns(axes), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in runs if r is not None)
    return _atomic_text(Path(path), buf.getvalue())


def format_progress(k: int, n: int, row: dict, keys: Sequence[str]) -> str:
    """``[k/n] rotation.speed_hz=21: exact, 17 events, closed 3.1 %, 0.25 s`` (or the error).

    >>> format_progress(1, 5, {"s": 21, "method": "exact", "events": 17, "closed_fraction": 0.031,
    ...                        "run_wall_s": 0.25, "error": ""}, ["s"])
    '[1/5] s=21: exact, 17 events, closed 3.1 %, 0.25 s'
    """
    head = f"[{k}/{n}] " + ", ".join(f"{key}={_num(row[key])}" for key in keys)
    if row.get("error"):
        return f"{head}: failed: {row['error']}"
    return (f"{head}: {row['method']}, {row['events']} events, closed {100 * row['closed_fraction']:.1f} %, "
            f"{row['run_wall_s']:.2f} s")


@dataclass
class _Plan:
    points: list[dict]
    scenes: list
    fixed: list[str]
    axes: list[Axis]
    method: str
    scene_text: str
    fp: str


def plan(scene_path, overrides: Sequence[str], method: str | None = None) -> _Plan:
    """Validate everything (ranges, the scene with its fixed overrides, every point) before any run."""
    from .scene import METHODS, load_scene

    fixed, axes = parse_ranges(overrides)
    base = load_scene(scene_path, fixed)
    if not axes:
        raise NsfemError("nsfem sweep: nothing to sweep; give at least one --set KEY=START:STOP:N")
    if method is not None and method not in METHODS:
        raise NsfemError(f"simulation.method {method!r} is not available (use {' | '.join(METHODS)})")
    points = sweep_values(axes)
    scenes = [load_scene(scene_path, fixed + point_overrides(p)) for p in points]
    method = method or base["simulation"]["method"]
    if any(a.key == "simulation.method" for a in axes):  # pragma: no cover - ranges are numbers
        raise NsfemError("simulation.method cannot be swept")
    text = scene_source(scene_path)
    return _Plan(points, scenes, fixed, axes, method, text,
                 fingerprint(text, fixed, [a.key for a in axes], method))


def _check_folder(out: Path, p: _Plan, scene_path) -> None:
    """Refuse a folder that holds another sweep (other scene text, fixed overrides, swept keys or method)."""
    stamp = out / "sweep-id.json"
    mine = {"fingerprint": p.fp, "scene": str(scene_path or "(shipped scene)"), "fixed": p.fixed,
            "keys": [a.key for a in p.axes], "method": p.method}
    if stamp.is_file():
        try:
            theirs = json.loads(stamp.read_text())
        except ValueError:
            theirs = {}
        if theirs.get("fingerprint") != p.fp:
            raise NsfemError(f"{out} holds another sweep (scene {theirs.get('scene')}, fixed {theirs.get('fixed')}, "
                             f"swept {theirs.get('keys')}, method {theirs.get('method')}); its results would mix "
                             "with this one's: choose another --out or remove that folder")
    else:
        write_json(stamp, mine)


def _client(client, workers: int | None, scheduler: str | None, n_runs: int):
    """(client, things to close): the given client, one connected to ``scheduler``, or a LocalCluster."""
    from distributed import Client, LocalCluster

    if client is not None:
        return client, []
    if scheduler:
        try:
            c = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise NsfemError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        return c, [c]
    n = workers or max(1, min(os.cpu_count() or 1, n_runs))
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    import logging

    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR, env=env)
    c = Client(cluster)
    return c, [c, cluster]


def run_sweep(scene_path, overrides: Sequence[str], out_dir=None, method: str | None = None, client=None,
              workers: int | None = None, scheduler: str | None = None,
              progress: Callable[[str], None] | None = None, plot: bool = True) -> SweepResult:
    """Run a sweep; returns its rows in sweep order (``runs``) with ``info``.

    ``client``: a ``distributed.Client`` to use; else ``scheduler`` (an address) or a
    LocalCluster of ``workers`` processes (default: one per core, at most one per run), one
    thread each. ``out_dir`` defaults to ``<output.dir>/sweep``. Runs already done in
    ``out_dir`` by the same sweep are not run again; failed ones are. ``progress(line)``
    receives one line per finished run. Ctrl-C cancels the pending runs and keeps the table
    of the finished ones. ``info``: ``executed``, ``resumed``, ``models_built``, ``workers``,
    ``wall_s``.
    """
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    if workers is not None and (scheduler or client is not None):
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")
    if workers is not None and workers < 1:
        raise NsfemError(f"--workers must be a positive integer, got {workers}")
    t0 = time.perf_counter()
    p = plan(scene_path, overrides, method)
    # absolute: the workers (maybe started elsewhere) write there
    out = (Path(out_dir) if out_dir is not None else Path(p.scenes[0]["output"]["dir"]) / "sweep").absolute()
    _check_folder(out, p, scene_path)
    keys = [a.key for a in p.axes]
    runs: list[dict | None] = [read_record(out / run_name(pt), p.fp) for pt in p.points]
    todo = [i for i, r in enumerate(runs) if r is None]
    resumed = len(p.points) - len(todo)
    res = SweepResult(p.axes, p.points, runs, out, out / "sweep.csv",
                      info={"executed": 0, "resumed": resumed, "models_built": 0, "workers": 0, "wall_s": 0.0})
    say = progress or (lambda line: None)
    if resumed:
        say(f"{resumed} of {len(p.points)} runs already done in {out}")

    def record(i: int, row: dict) -> None:
        runs[i] = row
        write_table(res.table, p.axes, runs)
        write_json(out / "sweep.json", res.to_json())

    def finish() -> SweepResult:
        res.info["wall_s"] = time.perf_counter() - t0
        write_table(res.table, p.axes, runs)
        if plot and any(r is not None and not r.get("error") for r in runs):
            from .plot.sweep import plot_resonance

            res.figure = plot_resonance(out / "resonance.png", keys, p.points, runs, p.scenes[0]["title"])
        write_json(out / "sweep.json", res.to_json())
        return res

    if not todo:
        return finish()
    # one model and reduction per distinct model key, built here once
    groups: dict[str, list[int]] = {}
    for i in todo:
        groups.setdefault(model_key(p.scenes[i]), []).append(i)
    built = {}
    for mk, idx in groups.items():
        scene = p.scenes[idx[0]]
        model = build_model(scene)
        built[mk] = (model, scene_reduction(scene, model))
    res.info["models_built"] = len(built)
    cl, closing = _client(client, workers, scheduler, len(todo))
    futures = {}
    try:
        res.info["workers"] = len(cl.nthreads())
        from distributed import as_completed

        for mk, idx in groups.items():
            [shared] = cl.scatter([built[mk]], broadcast=True, hash=False)
            for i in idx:
                # a fresh key: the scheduler must never hand back a finished task of an earlier sweep
                fut = cl.submit(run_point, p.scenes[i], p.method, shared, str(out / run_name(p.points[i])),
                                p.scene_text + "\n# overrides: " + " ".join(p.fixed + point_overrides(p.points[i])),
                                p.points[i], p.fp, key=f"nsfem-run-{uuid.uuid4().hex}", pure=False)
                futures[fut] = i
        done = 0
        try:
            for fut in as_completed(list(futures)):
                i = futures[fut]
                try:
                    row = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker, an unpicklable result
                    row = {**p.points[i], **dict.fromkeys(RUN_KEYS), "method": p.method,
                           "error": f"{type(exc).__name__}: {exc}", "result": "", "run_wall_s": 0.0}
                done += 1
                res.info["executed"] = done
                record(i, row)
                say(format_progress(resumed + done, len(p.points), row, keys))
        except KeyboardInterrupt:
            cl.cancel([f for f in futures if not f.done()])
            finish()
            raise
    finally:
        for c in closing:
            c.close()
    return finish()
