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
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from .atomic import check_folder, write_text_atomic
from .errors import IntegrationError, NsfemError
from .result import json_default

#: Scene tables that enter neither the assembled model nor its reduction basis (build_model
#: reads the stack and scene.mesh_options, scene_reduction scene.reduction, the contact set
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


def fingerprint(base, keys: Sequence[str], method: str) -> str:
    """Hash of what makes two sweeps' runs comparable: the validated scene (every default filled in,
    fixed overrides applied, ``[output]`` and the swept keys left out, the mesh file's bytes), the
    swept keys and the method. Reordered or no-op ``--set`` flags give the same fingerprint."""
    tree = json.loads(json.dumps(dict(base), default=str))
    tree.pop("output", None)
    for key in keys:
        _drop(tree, key)
    mesh = base.mesh_file
    mesh_hash = hashlib.sha256(mesh.read_bytes()).hexdigest() if mesh is not None and mesh.is_file() else ""
    blob = json.dumps({"scene": tree, "mesh": mesh_hash, "keys": list(keys), "method": method}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


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
    return write_text_atomic(path, json.dumps(payload, indent=1, default=_default) + "\n")


def _default(o):
    """numpy values as Python values (:func:`nsfem.result.json_default`), anything else as text."""
    try:
        return json_default(o)
    except TypeError:
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
        row.update(summary, error=error, result=str(path), outputs=[str(path)],
                   integration_wall_s=summary["wall_s"])
        row.update(sensor_amplitudes(result, system))
    except Exception as exc:  # noqa: BLE001 - every failure is reported in its row
        row["error"] = _message(exc)
    row["wall_s"] = time.perf_counter() - t0  # as nsfem run: the whole run (the shared model built before)
    row["warnings"] = warnings
    write_json(run_dir / "record.json", {"fingerprint": fp, "point": point, "row": row})
    return row


#: the columns of sensor amplitudes: ``amplitude_<sensor name>_m``
AMPLITUDE = "amplitude_{}_m"


def sensor_amplitudes(result, system) -> dict:
    """Per sensor of the run, half its peak-to-peak over the last half of the run [m] (the steady
    response's amplitude once the start has died out): the resonance curve of a rotor without contacts."""
    from .simulate import sensor_signals

    sensors = system.info.get("sensors", ())
    if not sensors or result.t.size < 2:
        return {}
    values = sensor_signals(result, system)
    half = result.t >= result.t[0] + 0.5 * (result.t[-1] - result.t[0])
    return {AMPLITUDE.format(s.name): float(np.ptp(values[half, k]) / 2) for k, s in enumerate(sensors)}


def _message(exc: BaseException) -> str:
    text = str(exc) if isinstance(exc, NsfemError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())


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
            or row.get("completed") is not True):
        return None
    return row if Path(row["result"]).is_file() else None


# --------------------------------------------------------------------------- the sweep (on the client)
#: Seconds to connect to a scheduler and for its first worker to be there; seconds to close a cluster.
CONNECT_TIMEOUT = 10.0
CLOSE_TIMEOUT = 2.0
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

    def set_row(self, point: dict, row: dict | None) -> None:
        """Enter (or replace) a point's row; ``points``/``runs`` stay sorted by the swept values."""
        name = run_name(point)
        if row is None and name in self.entries:
            return
        self.entries[name] = (point, row)
        keys = [a.key for a in self.axes]
        order = sorted(self.entries.values(), key=lambda e: tuple(e[0][k] for k in keys))
        self.points = [e[0] for e in order]
        self.runs = [e[1] for e in order]

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


def table_columns(axes: Sequence[Axis], runs: Sequence[dict | None] = ()) -> list[str]:
    """The swept keys, the run keys, the sensors' amplitudes the rows hold, error and result file."""
    amplitudes = sorted({k for r in runs if r for k in r if k.startswith("amplitude_") and k.endswith("_m")})
    return [a.key for a in axes] + list(RUN_KEYS) + amplitudes + ["error", "result"]


def write_table(path: Path, axes: Sequence[Axis], runs: Sequence[dict | None]) -> Path:
    """The CSV of the finished rows (atomically); unfinished points are left out."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=table_columns(axes, runs), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in runs if r is not None)
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
        if isinstance(point, dict) and list(point) == list(keys) and isinstance(row, dict):
            found.append((point, row))
    return found


def format_progress(k: int, n: int, row: dict, keys: Sequence[str]) -> str:
    """``[k/n] rotation.speed_hz=21: exact, 17 events, closed 3.1 %, 0.25 s`` (or the error).

    >>> format_progress(1, 5, {"s": 21, "method": "exact", "events": 17, "closed_fraction": 0.031,
    ...                        "wall_s": 0.25, "error": ""}, ["s"])
    '[1/5] s=21: exact, 17 events, closed 3.1 %, 0.25 s'
    """
    head = f"[{k}/{n}] " + ", ".join(f"{key}={_num(row[key])}" for key in keys)
    if row.get("error"):
        return f"{head}: failed: {row['error']}"
    return (f"{head}: {row['method']}, {row['events']} events, closed {100 * row['closed_fraction']:.1f} %, "
            f"{row['wall_s']:.2f} s")


@dataclass
class _Plan:
    points: list[dict]
    scenes: list
    fixed: list[str]
    axes: list[Axis]
    method: str
    scene_text: str
    fp: str
    base: Any = None


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
    method = method or base.simulation.method
    if any(a.key == "simulation.method" for a in axes):  # pragma: no cover - ranges are numbers
        raise NsfemError("simulation.method cannot be swept")
    keys = [a.key for a in axes]
    return _Plan(points, scenes, fixed, axes, method, scene_source(scene_path), fingerprint(base, keys, method),
                 base)


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
                             f"swept {theirs.get('keys')}, method {theirs.get('method')}); its results would mix "
                             "with this one's: choose another --out or remove that folder")
    elif write:
        write_json(stamp, {"fingerprint": p.fp, "scene": str(scene_path or "(shipped scene)"), "fixed": p.fixed,
                           "keys": [a.key for a in p.axes], "method": p.method})


def _client(client, workers: int | None, scheduler: str | None, n_runs: int):
    """(client, things to close): the given client, one connected to ``scheduler``, or a LocalCluster.
    Any failure to connect, or a cluster without workers, is a one-line NsfemError."""
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
        n = workers or max(1, min(os.cpu_count() or 1, n_runs))
        env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        # the workers ignore SIGINT: Ctrl-C in the terminal (sent to the whole process group)
        # reaches only this process, which cancels the runs and closes the cluster, quietly
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR, env=env, preload=[_IGNORE_SIGINT])
        c = Client(cluster)
        closing, where = [c, cluster], "the local cluster"
    try:
        c.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
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
              progress: Callable[[str], None] | None = None, plot: bool = True) -> SweepResult:
    """Run a sweep; returns the rows of its folder in the order of the swept values with ``info``.

    ``client``: a ``distributed.Client`` to use; else ``scheduler`` (an address) or a
    LocalCluster of ``workers`` processes (default: one per core, at most one per run), one
    thread each. ``out_dir`` defaults to ``<output.dir>/sweep-<swept keys>``. Runs already done in
    ``out_dir`` by the same sweep are not run again; failed ones are. ``progress(line)``
    receives one line per finished run (and one per warning of it). A model that cannot be
    built fails the rows of its values only. Ctrl-C cancels the pending runs, writes the table
    of the finished ones and raises :class:`SweepInterrupted` (a KeyboardInterrupt) carrying
    them. ``info``: ``executed``, ``resumed``, ``models_built``, ``workers``, ``wall_s``
    (and ``interrupted``).
    """
    if workers is not None and (scheduler or client is not None):
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")
    if workers is not None and workers < 1:
        raise NsfemError(f"--workers must be a positive integer, got {workers}")
    t0 = time.perf_counter()
    p = plan(scene_path, overrides, method)
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
                      info={"executed": 0, "resumed": resumed, "models_built": 0, "workers": 0, "wall_s": 0.0})
    for point, row in folder_rows(out, p.fp, keys):  # earlier sweeps into this folder, this one's resumed runs
        res.set_row(point, row)
    for pt in p.points:
        res.set_row(pt, None)
    say = progress or (lambda line: None)

    def record(i: int, row: dict) -> None:
        res.set_row(p.points[i], row)
        write_table(res.table, p.axes, res.runs)
        write_json(out / "sweep.json", res.to_json())
        res.info["executed"] += 1
        say(format_progress(resumed + res.info["executed"], len(p.points), row, keys))
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
    cl, closing, futures = None, [], {}
    try:
        cl, closing = _client(client, workers, scheduler, len(todo))
        res.info["workers"] = len(cl.nthreads())
        _check_folder(out, p, scene_path, write=True)
        if resumed:
            say(f"{resumed} of {len(p.points)} runs already done in {out}")
        from distributed import as_completed

        # one model and reduction per distinct model key, built here once; a failed build fails its rows only
        groups: dict[str, list[int]] = {}
        for i in todo:
            groups.setdefault(model_key(p.scenes[i]), []).append(i)
        for idx in groups.values():
            scene = p.scenes[idx[0]]
            try:
                model = build_model(scene)
                built = (model, scene_reduction(scene.reduction, model))
            except Exception as exc:  # noqa: BLE001 - reported in the rows of this model's values
                for i in idx:
                    row = error_row(p.points[i], p.method, f"model build failed: {_message(exc)}")
                    write_json(out / run_name(p.points[i]) / "record.json",
                               {"fingerprint": p.fp, "point": p.points[i], "row": row})
                    record(i, row)
                continue
            res.info["models_built"] += 1
            [shared] = cl.scatter([built], broadcast=True, hash=False)
            for i in idx:
                # a fresh key: the scheduler must never hand back a finished task of an earlier sweep
                fut = cl.submit(run_point, p.scenes[i], p.method, shared, str(out / run_name(p.points[i])),
                                p.scene_text + "\n# overrides: " + " ".join(p.fixed + point_overrides(p.points[i])),
                                p.points[i], p.fp, key=f"nsfem-run-{uuid.uuid4().hex}", pure=False)
                futures[fut] = i
        for fut in as_completed(list(futures), loop=cl.loop):
            i = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker, an unpicklable result
                row = error_row(p.points[i], p.method, _message(exc))
            record(i, row)
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
    finally:
        _close(closing)
    return finish()
