"""A scene's branch of periodic orbits over one of its keys (``nsfem periodic --continue KEY=LOW:HIGH``).

The orbit at the scene's value of KEY is found as ``nsfem periodic`` finds it (:func:`.scene.orbit_of_scene`:
a transient, then the shooting), or, when that value lies outside [LOW, HIGH], the orbit of the scene with KEY
at the nearer end. From there :func:`.branch.orbit_branch` follows the branch by pseudo-arclength towards each
end of the range the start is not at (both sides when the start lies inside), with its stability and its
bifurcations, and switches onto the period-doubled branches.

Systems along the branch: for ``rotation.speed_hz`` one model and one reduction (the scene's), the system at
speed p built from them (:meth:`~nsfem.integrate.ContactSystem.from_scene`: gyroscopic, centrifugal and
unbalance terms, bearing tables read at p), forcing period 1 / p; for any other numeric key the scene is loaded
again with KEY = p (one model and reduction per value; the forcing period 1 / rotation.speed_hz of that scene).
Keys of the mesh and the reduction change the coordinates themselves (a section state of one value means nothing
at another) and are refused, as are keys that do not shape the orbit (simulation, output, initial).

Per point the JSON reports what ``nsfem periodic`` does of an orbit: the key's value, ``period_s``,
``converged``, ``residual``, ``multipliers``, ``stable``, ``events_per_period`` and ``amplitudes`` (half the
peak-to-peak of each sensor over one period, from a flow over the period at that point).

>>> from nsfem import load_scene
>>> from nsfem.periodic.scene_branch import branch_of_scene
>>> sb = branch_of_scene(load_scene("critical_speed"), "rotation.speed_hz", 20.0, 30.0)   # doctest: +SKIP
>>> [(p["rotation.speed_hz"], p["amplitudes"]["disk_z"], p["stable"]) for p in sb.points]  # doctest: +SKIP
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..errors import NsfemError

if TYPE_CHECKING:
    from ..scene import Scene

#: the key whose systems share one model and reduction
SPEED_KEY = "rotation.speed_hz"
#: at most this many continuation steps per direction by default (``--steps``)
STEPS = 100
#: the largest ``--steps``
STEPS_MAX = 10_000
#: tables whose keys cannot be continued: the mesh and the reduction change the coordinates (a section state of
#: one value is no state at another); the others do not shape the orbit
FIXED_TABLES = ("mesh", "reduction", "simulation", "output", "initial")
#: systems kept (of other keys each with its own model and reduction): the corrector's last values and their p + dp
CACHED_SYSTEMS = 12


@dataclass
class SceneBranch:
    """A scene's branch of periodic orbits over ``key``: ``points`` (dicts, in order along the branch from the
    LOW side to the HIGH side), ``bifurcations`` ([{"kind", "value", ...}]), ``doubled`` (the period-doubled
    branches switched onto, each {"multiple", "points", "bifurcations", "stop", "reason"}), ``sides`` (per
    direction followed: {"towards", "stop", "reason", "reanchors": [{"value", "t0_s", "forced"}]: where the section
    moved}), ``start`` (the :class:`~.scene.SceneOrbit` it started
    from) and the arrays of the points' section states (``q0``, ``v0``: (points, n))."""

    key: str
    low: float
    high: float
    scene_value: float
    start_value: float
    multiple: int
    points: list[dict]
    bifurcations: list[dict]
    doubled: list[dict]
    sides: list[dict]
    start: object
    sensors: tuple
    warnings: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    interrupted: bool = False
    #: the Dask cluster's worker threads that followed it (0: this process)
    workers: int = 0

    @property
    def stop(self) -> str:
        """'interrupted', 'end' when every side reached its end of the range, else the first other side's stop."""
        if self.interrupted:
            return "interrupted"
        other = [s for s in self.sides if s["stop"] != "end"]
        return other[0]["stop"] if other else "end"

    def to_json(self) -> dict:
        """The ``nsfem periodic --continue`` keys (design section 9: ``branch``, ``bifurcations``) and additions."""
        def public(p: dict) -> dict:
            return {k: v for k, v in p.items() if k not in ("q0", "v0")}

        return {"key": self.key, "low": self.low, "high": self.high, "scene_value": self.scene_value,
                "start_value": self.start_value, "multiple": self.multiple,
                "branch": [public(p) for p in self.points],
                "bifurcations": [public(b) for b in self.bifurcations],
                "doubled_branches": [{**d, "points": [public(p) for p in d["points"]],
                                      "bifurcations": [public(b) for b in d["bifurcations"]]} for d in self.doubled],
                "stop": self.stop, "reason": "; ".join(f"towards {s['towards']:g}: {s['reason']}" for s in self.sides)
                or (("interrupted before the first step" if len(self.points) <= 1 else
                     f"interrupted after {len(self.points)} points") if self.interrupted else ""),
                "sides": list(self.sides), "sensors": [s.name for s in self.sensors], "workers": self.workers,
                "warnings": list(self.warnings)}


def check_branch_options(steps, step, low: float, high: float) -> None:
    """Refuse bad ``--steps`` and ``--step`` before any computation (one line naming the option)."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 1 <= steps <= STEPS_MAX:
        raise NsfemError(f"--steps must be an integer from 1 to {STEPS_MAX} (continuation steps per direction), "
                         f"got {steps!r}")
    if step is not None:
        span = abs(high - low)
        if isinstance(step, bool) or not (isinstance(step, (int, float)) and math.isfinite(step) and 0 < step <= span):
            raise NsfemError(f"--step must be a number > 0 and at most the range's length {span:g} (the first step, "
                             f"in the key's unit), got {step!r}")


def check_key(key: str) -> None:
    """Refuse a key of :data:`FIXED_TABLES` (one line saying why)."""
    table = key.split(".", 1)[0]
    if table in ("mesh", "reduction"):
        raise NsfemError(f"--continue {key}: the {table} sets the coordinates themselves, so the orbits at two "
                         "values have no common state to continue; compute orbits at each value (--set)")
    if table in FIXED_TABLES:
        raise NsfemError(f"--continue {key}: [{table}] does not shape the periodic orbit; continue a physical key "
                         "such as rotation.speed_hz or stator.0.friction")


def scene_value(scene: "Scene", key: str) -> float:
    """The number at dotted ``key`` of the scene's tree."""
    node = dict(scene)
    for part in key.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return float(node)


def check_speeds(scene: "Scene", low: float, high: float) -> None:
    """Refuse a speed range the scene's model cannot spin at: a speed <= 0, beyond the centrifugal limit, outside
    a bearing's table, or a frame that cannot carry the rotor once it spins."""
    from ..scene.checks import check_frame_at_speed, check_speed

    if low <= 0:
        raise NsfemError(f"--continue {SPEED_KEY}: the speeds must be > 0 Hz (a rotor at rest has no periodic "
                         f"forcing), got {low:g}")
    check_speed(high, scene.stack, f"--continue {SPEED_KEY}")
    scene.stack.check_speeds([low, high])
    check_frame_at_speed(scene.rotation.frame, scene.stack)


def table_edge(scene: "Scene", low: float, high: float) -> tuple[str, float] | None:
    """(the key of a bearing table, the range's end) where an end of [low, high] is an end of that table."""
    for b in scene.stack.bearings:
        if b.table:
            lo, hi = b.table[0][0], b.table[0][-1]
            for end in (low, high):
                if end in (lo, hi):
                    return f"{b.label or 'bearing'}.speeds_hz", end
    return None


def branch_of_scene(scene: "Scene", key: str, low: float, high: float, *, multiple: int = 1, start=None,
                    transient_periods: int | None = None, tol: float = 1e-9, steps: int = STEPS,
                    step: float | None = None, load: Callable[[list[str]], "Scene"] | None = None,
                    warn: Callable[[str], None] | None = None, progress: Callable[[str], None] | None = None,
                    on_point: Callable[["SceneBranch"], None] | None = None, client=None,
                    workers: int | None = None, scheduler: str | None = None) -> SceneBranch:
    """The branch of ``scene``'s periodic orbits (period ``multiple`` forcing periods) over ``key`` in [low, high]
    (see the module's docstring). ``start``, ``transient_periods``, ``tol``: as for :func:`.scene.orbit_of_scene`
    (the first orbit); ``steps``: continuation steps per direction; ``step``: the first step in the key's unit
    (default a fiftieth of the range); ``load(overrides)``: the scene with extra ``--set`` overrides (default
    :func:`reloader`); ``warn(text)`` the warnings, ``progress(text)`` a line per point; ``on_point(branch)`` is
    called with the branch so far after each point (to save it). Bad options and keys raise
    :class:`~nsfem.errors.NsfemError` before any computation. Ctrl-C returns the branch so far
    (``interrupted``).

    On a Dask cluster (``client``: a ``distributed.Client``; else ``scheduler``: an address; else ``workers`` >= 2
    local worker processes, as ``nsfem sweep``), the independent pieces run as tasks: the two sides of a start
    inside the range, then each side's period-doubled branches (:mod:`.branch_cluster`); the start's orbit is
    computed here once. The points are those of the serial path (the same arithmetic), merged in its order.
    Without any of them, or with ``workers=1``, everything runs in this process."""
    from .scene import check_continuation, check_options, check_scene

    t_wall = time.perf_counter()
    check_options(multiple, transient_periods, tol, None)
    for name, v in (("LOW", low), ("HIGH", high)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise NsfemError(f"--continue {key}: {name} must be a finite number, got {v!r}")
    if low == high:
        raise NsfemError(f"--continue {key}: LOW and HIGH are the same value ({low!r}); a branch needs a range")
    check_branch_options(steps, step, low, high)
    check_key(key)
    check_scene(scene)
    from .branch_cluster import check_cluster_options

    on_cluster = check_cluster_options(client, workers, scheduler)
    a, b = sorted((float(low), float(high)))
    at_speed = key == SPEED_KEY and load is None   # (one model: the scene is not loaded again)
    if key == SPEED_KEY:
        check_speeds(scene, a, b)
        load = (lambda extra: scene) if load is None else load
    elif load is None:
        raise NsfemError(f"branch_of_scene: continuing {key} loads the scene at each value: give load(overrides) -> "
                         "Scene, e.g. lambda extra: load_scene(PATH, [*overrides, *extra])")
    else:
        check_continuation(scene, key, low, high, load)
    value = scene_value(scene, key)
    inside = a <= value <= b
    p0 = value if inside else min((a, b), key=lambda e: abs(e - value))
    scene0 = scene if inside else _with_speed(scene, p0) if at_speed else load([f"{key}={p0!r}"])
    check_scene(scene0)
    warnings: list[str] = []

    def say(text: str) -> None:
        warnings.append(text)
        if warn is not None:
            warn(text)

    if key == SPEED_KEY:
        edge = table_edge(scene, a, b)
        if edge is not None:
            say(f"{edge[0]}: the range's end {edge[1]:g} Hz is the end of the bearing's table: the continuation "
                "steps a little past its ends (predictor, difference quotients), where the table has no "
                "coefficients, so that side stops just short of it; extend the table beyond the range")
    sides = [e for e in ((low, high) if low < high else (high, low)) if e != p0]
    cluster = None
    if on_cluster:   # connected (or started) before the start's orbit: a bad address is refused first
        from .branch_cluster import connect

        cluster = connect(client, workers, scheduler, len(sides))
    try:
        return _branch(scene, key, low, high, value, p0, scene0, sides, multiple, start, transient_periods, tol,
                       steps, step, load, say, warnings, progress, on_point, cluster, t_wall)
    finally:
        if cluster is not None:
            from .branch_cluster import close

            close(cluster)


def _branch(scene, key, low, high, value, p0, scene0, sides, multiple, start, transient_periods, tol, steps, step,
            load, say, warnings, progress, on_point, cluster, t_wall) -> SceneBranch:
    """:func:`branch_of_scene` once checked (and its cluster, if any, connected)."""
    from .scene import orbit_of_scene

    so = orbit_of_scene(scene0, multiple, start, transient_periods, tol, warn=say,
                        progress=bool(progress))
    if not so.orbit.converged:
        raise NsfemError(f"--continue {key}: no periodic orbit at {key} = {p0:g} to start the branch from (the "
                         f"shooting's residual {so.orbit.residual:.3g} > --tol {tol:g}); try a longer --transient")
    family = _Family(scene0, key, so.system, load)
    # the branch's points in order: the LOW side reversed, then the HIGH side
    sb = SceneBranch(key, float(low), float(high), value, p0, int(multiple), [], [], [], [], so, tuple(scene0.sensors),
                     warnings)
    if cluster is not None:
        sb.workers = int(sum(cluster[0].nthreads().values()))   # (threads: a worker may run several tasks)
    found: list[list[dict]] = [[] for _ in sides]
    doubled_found: dict[int, list[dict]] = {}
    records: dict[tuple, dict] = {}   # (multiple, p, u's bytes) -> the point's record, for the doubled branches

    def accept(rec: dict, mult: int, side: int) -> None:
        """A point's record as it comes: kept, a progress line, the branch so far handed to ``on_point``."""
        if mult == multiple:
            found[side].append(rec)
        else:
            doubled_found.setdefault(mult, []).append(rec)
        if progress is not None:
            amp = ", ".join(f"{k} {1e6 * v:.4g} um" for k, v in list(rec["amplitudes"].items())[:2])
            progress(f"{key} = {rec['value']:.8g}: {'stable' if rec['stable'] else 'unstable'}"
                     + (f" ({rec['loss']})" if rec["loss"] else "") + (f", {amp}" if amp else "")
                     + ("" if rec["converged"] else ", NOT converged") + f" [{time.perf_counter() - t_wall:.1f} s]")
        _assemble(sb, found, sides, p0)
        if on_point is not None:
            on_point(sb)

    def point(bp, mult: int, side: int) -> None:
        rec = point_record(family, bp, mult, key, so.orbit.t0)
        records[record_key(mult, bp.p, bp.u)] = rec
        accept(rec, mult, side)

    def merge(k: int, stop: str, reason: str, bifurcations: list[dict], doubled: list[dict],
              reanchors: list[dict] = ()) -> None:
        """Side k's end, bifurcations, doubled branches and section moves into the branch (sides in their
        order)."""
        end = sides[k]
        moves = [{name: r[name] for name in ("value", "t0_s", "forced")} for r in reanchors]
        sb.sides.append({"towards": float(end), "stop": stop, "reason": reason, "reanchors": moves})
        if moves and progress is not None:
            at = ", ".join(format(r["value"], ".6g") for r in moves[:5]) + (", ..." if len(moves) > 5 else "")
            progress(f"towards {key} = {end:g} the section moved {len(moves)} time(s) off events of the "
                     f"orbit that drifted onto it (at {at})")
        for bif in bifurcations:
            failed = {"switch_failed": bif["switch_failed"]} if "switch_failed" in bif else {}
            sb.bifurcations.append({"kind": bif["kind"], "value": bif["value"], "side": float(end), **failed,
                                    **{k: bif[k] for k in ("accuracy", "located", "events_per_period") if k in bif}})
        sb.doubled.extend(doubled)
        if stop == "failed":
            say(f"the branch towards {key} = {end:g} ended early: {reason}")

    from .branch import orbit_branch
    from .scene import interrupts_end_flows

    try:
        # (Ctrl-C inside a flow too: the integrator ends it cleanly, which the corrector would take for a failed
        # step and go on)
        with interrupts_end_flows():
            if cluster is not None:
                from .branch_cluster import follow_sides

                follow_sides(cluster[0], family, so, sides, p0, key=key, multiple=multiple, tol=tol, step=step,
                             steps=steps, accept=accept, merge=merge)
            for k, end in enumerate(sides if cluster is None else ()):
                br = orbit_branch(family.system_at, family.period_at, so.orbit.q0, so.orbit.v0, p0, end, key=key,
                                  multiple=multiple, t0=float(so.orbit.t0), tol=tol, step=step, max_steps=steps,
                                  on_point=lambda bp, m, k=k: point(bp, m, k))
                # (each point of a doubled branch at its own section, as its record made when it came)
                merge(k, br.stop, br.reason, br.bifurcations, [_doubled(d, family, records) for d in br.doubled],
                      br.reanchors)
    except KeyboardInterrupt:
        sb.interrupted = True
    sb.bifurcations.sort(key=lambda b: b["value"])
    _assemble(sb, found, sides, p0)
    if sb.interrupted and not sb.doubled and doubled_found:
        sb.doubled = [{"multiple": m, "points": pts, "bifurcations": [], "stop": "interrupted", "reason": "",
                       "reanchors": []}
                      for m, pts in doubled_found.items()]
    sb.wall_s = time.perf_counter() - t_wall
    return sb


def record_key(multiple: int, p: float, u) -> tuple:
    """The key of a point's record: (multiple, p, u's bytes)."""
    return (int(multiple), float(p), np.asarray(u, dtype=float).tobytes())


def point_record(family: "_Family", bp, multiple: int, key: str, t0: float) -> dict:
    """The JSON record of the continuation's point ``bp`` (a :class:`~.continuation.BranchPoint` of an orbit of
    period ``multiple`` forcing periods): :meth:`_Family.point` at the point's own section (``bp.t0_s``: it moves
    off drifting events; ``t0`` for a point without one), the key's value, the corrector's residual, the
    multipliers and the verdict."""
    t0 = float(getattr(bp, "t0_s", t0))
    rec = family.point(bp.p, bp.u, multiple, t0)
    rec.update({"value": float(bp.p), key: float(bp.p), "t0_s": t0, "converged": bool(bp.converged),
                "residual": float(bp.residual) if math.isfinite(bp.residual) else rec["residual"]})
    _stability(rec, bp.multipliers)
    return rec


def _with_speed(scene: "Scene", speed_hz: float) -> "Scene":
    """``scene`` at rotation.speed_hz = ``speed_hz`` (the typed part, which builds the system; the tree is the
    user's)."""
    import copy
    from dataclasses import replace

    out = copy.copy(scene)
    out.rotation = replace(scene.rotation, speed_hz=float(speed_hz))
    return out


def _assemble(sb: SceneBranch, found: list[list[dict]], sides: list[float], p0: float) -> None:
    """sb.points in order along the branch: the side towards the lower end reversed, then the other (the start
    once)."""
    lower = [f for f, e in zip(found, sides) if e < p0]
    upper = [f for f, e in zip(found, sides) if e > p0]
    pts = list(reversed(lower[0])) if lower else []
    if upper:
        pts += upper[0][1:] if pts else upper[0]
    sb.points = pts


def _stability(rec: dict, multipliers) -> None:
    from .shooting import classify

    mu = np.zeros(0, complex) if multipliers is None else np.asarray(multipliers, dtype=complex)
    stable, loss = classify(mu) if mu.size else (True, None)
    rec.update(multipliers=[[float(z.real), float(z.imag)] for z in mu], stable=bool(stable), loss=loss,
               largest_multiplier=float(np.abs(mu).max(initial=0.0)))


def _doubled(d, family: "_Family", records: dict) -> dict:
    """A doubled :class:`~.branch.OrbitBranch` as the JSON has it, its points with amplitudes (those reported as
    they were found, from ``records``; each point's at its own section ``t0_s``)."""
    pts = []
    for p in d.points:
        u = np.concatenate([p["q0"], p["v0"]])
        rec = records.get((d.multiple, float(p["value"]), u.tobytes()))
        if rec is None:
            rec = family.point(p["value"], u, d.multiple, p["t0_s"])
            rec.update({k: p[k] for k in ("value", d.key, "t0_s", "converged", "residual") if k in p})
            _stability(rec, [complex(*z) for z in p["multipliers"]])
        pts.append(rec)
    return {"multiple": d.multiple, "points": pts,
            "bifurcations": [{"kind": b["kind"], "value": b["value"]} for b in d.bifurcations],
            "stop": d.stop, "reason": d.reason,
            "reanchors": [{name: r[name] for name in ("value", "t0_s", "forced")} for r in d.reanchors]}


class _Family:
    """The systems, forcing periods and scenes along a branch over ``key`` (module docstring), and the report of
    a point (amplitudes from a flow over its period)."""

    def __init__(self, scene0: "Scene", key: str, system0, load: Callable):
        self.scene0, self.key, self.system0, self.load = scene0, key, system0, load
        self.n = system0.n
        self._cache: OrderedDict = OrderedDict()
        # one family serves the tasks of a multi-threaded Dask worker at once (both sides of a start): the cache is
        # read and changed under a lock, and a value being loaded by one thread is waited for by the others (one
        # load per value); the loads themselves run outside the lock (two values load in parallel)
        self._lock = threading.Lock()
        self._loading: dict[float, threading.Event] = {}

    def __getstate__(self) -> dict:
        """Pickled (sent to a cluster's workers) without its lock and loads under way."""
        state = self.__dict__.copy()
        del state["_lock"], state["_loading"]
        with self._lock:
            state["_cache"] = OrderedDict(self._cache)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock, self._loading = threading.Lock(), {}

    def fresh(self) -> "_Family":
        """The same family without its cached systems (to send to a cluster's workers)."""
        return _Family(self.scene0, self.key, self.system0, self.load)

    def scene_at(self, p: float) -> "Scene":
        return self.scene0 if self.key == SPEED_KEY else self._entry(p)[0]

    def system_at(self, p: float):
        """The system at p (cached: a branch point's report asks for its corrector's last system again)."""
        return self._entry(p)[1]

    def period_at(self, p: float) -> float:
        return 1.0 / (float(p) if self.key == SPEED_KEY else self.scene_at(p).rotation.speed_hz)

    def speed_at(self, p: float) -> float:
        return float(p) if self.key == SPEED_KEY else self.scene_at(p).rotation.speed_hz

    def _entry(self, p: float):
        """(scene, system) at p: from the cache, else loaded (once, whichever threads ask: see __init__)."""
        p = float(p)
        while True:
            with self._lock:
                hit = self._cache.get(p)
                if hit is not None:
                    self._cache.move_to_end(p)
                    return hit
                pending = self._loading.get(p)
                mine = pending is None
                if mine:
                    pending = self._loading[p] = threading.Event()
            if mine:
                break
            pending.wait()   # (then from the cache; or loaded here if its load failed or it was evicted since)
        try:
            entry = self._load(p)
            with self._lock:
                self._cache[p] = entry
                if len(self._cache) > CACHED_SYSTEMS:
                    self._cache.popitem(last=False)
            return entry
        finally:
            with self._lock:
                del self._loading[p]
            pending.set()

    def _load(self, p: float):
        """(scene, system) with the key at p, checked (at speed p: the start's model and reduction)."""
        from ..integrate import ContactSystem
        from .scene import check_scene

        if self.key == SPEED_KEY:
            info = self.system0.info
            return self.scene0, ContactSystem.from_scene(self.scene0, info["model"], info["reduction"], speed_hz=p)
        scene = self.load([f"{self.key}={p!r}"])
        check_scene(scene)
        system = ContactSystem.from_scene(scene)
        if system.n != self.n:
            raise NsfemError(f"--continue {self.key}: at {p:g} the system has {system.n} coordinates, at the start "
                             f"{self.n}: the key changes the model's coordinates")
        return scene, system

    def point(self, p: float, u: np.ndarray, multiple: int, t0: float) -> dict:
        """{period_s, residual (of a flow over the period, as the shooting measures it), events_per_period,
        amplitudes {sensor: half the peak-to-peak over the period [m]}, q0, v0} of the orbit through u at p."""
        from ..fem.constraints import dense
        from ..sensors import read
        from .flow import flow
        from .scene import SAMPLES_PER_REVOLUTION, half_peak_to_peak, impact_readings

        n = self.n
        q0, v0 = np.array(u[:n], dtype=float), np.array(u[n:], dtype=float)
        scene, system = self.scene_at(p), self.system_at(p)
        period = multiple * self.period_at(p)
        fl = flow(system, t0, q0, v0, period, jacobian=False, output_dt=period / (SAMPLES_PER_REVOLUTION * multiple))
        w = 2.0 * math.pi / period
        scale = np.concatenate([np.ones(n), np.full(n, 1.0 / w)])
        F = scale * np.concatenate([fl.q - q0, fl.v - v0])
        size = max(float(np.abs(scale * u).max()), float(np.abs(F).max()), 1e-300)
        res = fl.result
        amplitudes = {}
        if scene.sensors:
            offset = t0 - float(res.t[0])
            t = np.asarray(res.t, dtype=float) + offset
            rot = scene.rotation
            signals = read(scene.sensors, system.info["model"], dense(system.info["reduction"].T), t, res.q,
                           rot.frame, self.speed_at(p), rot.phase_deg)
            where, kinks = impact_readings(system, scene.sensors, t, res, offset, rot.frame, self.speed_at(p),
                                           rot.phase_deg)
            amplitudes = {s.name: half_peak_to_peak(signals[:, k], kinks=(where, kinks[:, k]))
                          for k, s in enumerate(scene.sensors)}
        return {"period_s": float(period), "residual": float(np.abs(F).max()) / size,
                "events_per_period": len(res.events), "amplitudes": amplitudes, "multiple": int(multiple),
                "section_q_max": float(np.abs(q0).max(initial=0.0)),
                "orbit_q_max": float(np.abs(np.asarray(res.q)).max(initial=0.0)),
                "q0": q0, "v0": v0}
