"""Stiff and extreme cases, each run with every integrator that applies.

Every case is the shipped scene (1 m steel shaft, delamination 0.1-0.9 m, 9 Dirac points,
40 elements, Craig-Bampton 16, 21 Hz, from rest) plus a few ``--set`` overrides: very fine
meshes and an unreduced model; 101/201 contact points (Dirac and hat); restitution 0 and 1
on the interface and on a stop under midspan (impact accumulation with eps 0.5, 0.9); friction
mu 0, 0.3, 1.5 with 4 and 8 cone generators (at 5 Hz with the stop pressing on midspan, where
the interface closes: at 21 Hz the centrifugal load keeps it open and friction never acts);
speeds inside and beyond the divergence bands (``nsfem campbell``: first band 43.4-48.0 Hz open,
43.7-48.0 Hz closed; at 120 Hz the open shaft flutters, growth rate 255 1/s, though outside
every divergence band); the start from rest (the opening mode grazes g = 0) and from the
stationary state; no rotation, no gravity; a free-free shaft (rigid-body modes); a very thin
sub-beam; a very short delamination; a very stiff penalty.

Each (case, method) runs in a forked child with a wall-time budget: at the budget the child
gets an interrupt (the integrators stop cleanly and return the run so far: status
``timeout`` with the time reached); a child that does not stop within a grace period is
killed (``killed``). Status: completed | failed (the integrator's error, IntegrationError) |
timeout | killed | refused (SceneError: the scene was rejected before any computation) |
setup-failed (another NsfemError before the integration) | crashed (any other exception: a bug).

Columns: events, impacts, energy (relative work-balance residual), min_gap_m (negative =
penetration, expected for penalty and moreau), max_gap_m, closed_fraction (share of the time
with a closed contact; of the output times for penalty and moreau), stick/slip_fraction (share
of output times, for the contacts with friction),
wall_s (setup + integration, one core), gap_diff (max |g - g_ref| / max |g_ref| over the output times, against ``exact``
of the same case, or ``rk`` where exact did not complete) and flags (the checks a row fails:
energy residual > 1e-6 for exact/rk, penetration by an event-driven method, > 1e5 events per
simulated second, disagreement > 10 % with the reference).

    python studies/extremes.py [--quick] [--json] [--case NAME ...] [--methods exact,rk,...]
                               [--budget S] [--list]

Budgets: 8 s per run with --quick (about 3 min in all on 2 shared cores), 30 s in full mode
(cases of 1 s simulated twice that; 37 min measured with 40 s on a loaded machine).
Writes extremes.csv/.json/.md into studies/out/extremes (``--quick``: extremes_quick.*; with
``--case`` or ``--methods``: *_partial.*) and prints the markdown table (``--json``: one JSON
object {"rows": [...], "summary": {...}, "machine": {... "commit"}}).
Each row carries ``reproduce``, the ``python -m nsfem run`` command line of that run. Outputs
are sampled every 0.1 ms (OUTPUT_DT); gap_diff leaves out the sample at t_end (see
``last_output_zero``: exact and rk leave it at zero when n * output_dt rounds above t_end).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import shlex
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

ALL = ("exact", "rk", "penalty", "moreau")
NO_PENALTY = ("exact", "rk", "moreau")  # penalty neglects friction: not applicable when mu > 0


def stop(eps: float, mu: float = 0.0, clearance: float = 2e-4) -> str:
    """A rigid stop 0.2 mm under midspan (the work-precision study's impact scene)."""
    return f'obstacle=[{{x=0.5, normal="-z", clearance={clearance:g}, restitution={eps:g}, friction={mu:g}}}]'


@dataclass
class Case:
    name: str
    description: str
    overrides: list = field(default_factory=list)
    methods: tuple = ALL
    t_quick: float = 0.02
    t_full: float = 0.2
    quick: bool = True  # part of --quick
    budget_factor: float = 1.0  # times the per-run budget
    expect: str = "completed"  # the status a correct library gives


CASES = [
    Case("shipped", "shipped scene: 21 Hz, from rest (the opening mode grazes g = 0 each period)", [],
         t_quick=0.1, t_full=1.0, budget_factor=2.0),
    Case("stationary", "start from the stationary state (LCP 28) instead of rest",
         ['initial.state="stationary"'], t_full=1.0, budget_factor=2.0),
    Case("t_end-roundoff", "shipped scene, t_end 0.03 s: 300 x 1e-4 rounds to 0.030000000000000002 > t_end",
         [], methods=("exact", "rk", "moreau"), t_quick=0.03, t_full=0.03),
    Case("no-rotation", "speed 0 with gravity: a static sag, the interface opens under its own weight",
         ["rotation.speed_hz=0"], quick=False),
    Case("no-gravity", "21 Hz without gravity: only the centrifugal load, which opens the interface",
         ["rotation.gravity=0"]),
    # meshes and reduction
    Case("mesh-320", "320 elements, Craig-Bampton 16", ["mesh.elements=320"]),
    Case("mesh-640", "640 elements, Craig-Bampton 16", ["mesh.elements=640"], quick=False),
    Case("mesh-1280", "1280 elements, Craig-Bampton 16", ["mesh.elements=1280"], t_full=0.1, quick=False),
    Case("unreduced-20", "20 elements, no reduction (every FE mode kept: kHz-MHz time scales)",
         ["mesh.elements=20", 'reduction.method="none"'], t_quick=0.005, t_full=0.05),
    Case("modal-16", "modal reduction (16 free-interface modes) instead of Craig-Bampton",
         ['reduction.method="modal"'], quick=False),
    # contact discretisation
    Case("points-101", "101 Dirac contact points, 128 elements (Craig-Bampton keeps 101 contact dofs)",
         ["delamination.0.contact_points=101", "mesh.elements=128"], t_quick=0.005, t_full=0.05),
    Case("points-201", "201 Dirac contact points, 256 elements",
         ["delamination.0.contact_points=201", "mesh.elements=256"], t_full=0.05, quick=False),
    Case("hat-101", "101 hat-weighted contacts (eq. 19), 128 elements",
         ["delamination.0.contact_points=101", 'delamination.0.weighting="hat"', "mesh.elements=128"],
         t_full=0.05, quick=False),
    # restitution
    Case("eps-1", "interface restitution 1 (elastic impacts, mu = 0: energy conserved)",
         ["delamination.0.restitution=1.0"], t_quick=0.1, t_full=1.0, budget_factor=2.0),
    Case("stop-eps0", "stop 0.2 mm under midspan, eps = 0 (plastic impacts, persistent contact)", [stop(0.0)]),
    Case("stop-eps0.5", "stop under midspan, eps = 0.5 (Zeno impact sequences each revolution)", [stop(0.5)]),
    Case("stop-eps0.9", "stop under midspan, eps = 0.9 (long impact sequences)", [stop(0.9)], quick=False),
    Case("stop-eps1", "stop under midspan, eps = 1 (elastic: energy conserved, chatter without end)",
         [stop(1.0)]),
    # friction: at 21 Hz the interface stays open (centrifugal load); at 5 Hz a stop touching midspan
    # (clearance 0) holds the lower sub-beam and the upper one lies on it: the interface closes and sticks;
    # thrown onto the stop at 0.1 m/s it sticks and slips
    Case("press-mu0", "5 Hz, stop at clearance 0 under midspan (eps 0): the interface closes, mu = 0",
         ["rotation.speed_hz=5", stop(0.0, clearance=0.0)]),
    Case("press-mu0.3", "as press-mu0 with interface friction mu = 0.3, r = 4",
         ["rotation.speed_hz=5", stop(0.0, clearance=0.0), "delamination.0.friction=0.3"], methods=NO_PENALTY),
    Case("press-mu1.5", "as press-mu0 with mu = 1.5, r = 4",
         ["rotation.speed_hz=5", stop(0.0, clearance=0.0), "delamination.0.friction=1.5"], methods=NO_PENALTY),
    Case("press-mu0.3-r8", "as press-mu0 with mu = 0.3, r = 8",
         ["rotation.speed_hz=5", stop(0.0, clearance=0.0), "delamination.0.friction=0.3",
          "delamination.0.friction_directions=8"], methods=NO_PENALTY, quick=False),
    Case("throw-mu0.3", "5 Hz, thrown at 0.1 m/s onto the stop (0.2 mm, eps 0), mu = 0.3: stick and slip",
         ["rotation.speed_hz=5", stop(0.0), "initial.velocity=[0.0,0.0,-0.1]", "delamination.0.friction=0.3"],
         methods=NO_PENALTY, t_quick=0.01, t_full=0.1),
    Case("throw-mu1.5", "as throw-mu0.3 with mu = 1.5",
         ["rotation.speed_hz=5", stop(0.0), "initial.velocity=[0.0,0.0,-0.1]", "delamination.0.friction=1.5"],
         methods=NO_PENALTY, t_quick=0.01, t_full=0.1),
    Case("rest-mu0.3", "no rotation, stop at clearance 0 under midspan, mu = 0.3 (starts in grazing contact)",
         ["rotation.speed_hz=0", stop(0.0, clearance=0.0), "delamination.0.friction=0.3"], methods=NO_PENALTY,
         t_quick=0.01, t_full=0.1),
    Case("open-mu0.3", "21 Hz, stop 0.2 mm (eps 0), mu = 0.3: the interface never closes (friction inactive)",
         [stop(0.0), "delamination.0.friction=0.3"], methods=NO_PENALTY, quick=False),
    Case("stop-mu0.3", "21 Hz, stop eps 0.5 with friction mu = 0.3 on the stop and the interface",
         [stop(0.5, mu=0.3), "delamination.0.friction=0.3"], methods=NO_PENALTY, quick=False),
    Case("pts101-mu0.3", "press-mu0.3 with 101 contact points, 128 elements",
         ["rotation.speed_hz=5", stop(0.0, clearance=0.0), "delamination.0.friction=0.3",
          "delamination.0.contact_points=101", "mesh.elements=128"], methods=NO_PENALTY, t_full=0.02, quick=False),
    # speeds
    Case("speed-46", "46 Hz: inside the first divergence band (43.4-48.0 Hz): the response grows",
         ["rotation.speed_hz=46"], t_quick=0.05, t_full=0.3),
    Case("speed-60", "60 Hz: past the first divergence band (gyroscopically stable?)", ["rotation.speed_hz=60"],
         quick=False),
    Case("speed-120", "120 Hz: past the open bands, inside the closed-interface band 99-170 Hz",
         ["rotation.speed_hz=120"]),
    Case("speed-120-stop", "120 Hz with the stop (eps 0.5) under midspan", ["rotation.speed_hz=120", stop(0.5)],
         quick=False),
    # structure
    Case("free-free", "free-free shaft: six rigid-body modes; gravity makes it fall", ['shaft.supports="free-free"']),
    Case("free-free-g0", "free-free shaft, no gravity, 21 Hz: centrifugal load only",
         ['shaft.supports="free-free"', "rotation.gravity=0"], quick=False),
    Case("clamped-free", "cantilever (clamped-free) with the delamination", ['shaft.supports="clamped-free"'],
         quick=False),
    Case("thin-0.019", "thin lower sub-beam: upper_height 0.019 of 0.02 m (1 mm below)",
         ["delamination.0.upper_height=0.019"], quick=False),
    Case("thin-0.0199", "very thin lower sub-beam: 0.1 mm below the interface",
         ["delamination.0.upper_height=0.0199"]),
    Case("thin-0.01997", "thinnest accepted sub-beam: 30 um below the interface (1.5e-3 of the height)",
         ["delamination.0.upper_height=0.01997"], quick=False),
    Case("short-1pt", "very short delamination 0.49-0.51 m, 1 contact point",
         ["delamination.0.start=0.49", "delamination.0.end=0.51", "delamination.0.contact_points=1"], quick=False),
    Case("short-3pt", "very short delamination 0.49-0.51 m, 3 contact points, 200 elements",
         ["delamination.0.start=0.49", "delamination.0.end=0.51", "delamination.0.contact_points=3",
          "mesh.elements=200"], t_quick=0.01, t_full=0.1),
    Case("short-stop", "very short delamination 0.495-0.505 m, 1 point, stop eps 0.5 under it",
         ["delamination.0.start=0.495", "delamination.0.end=0.505", "delamination.0.contact_points=1", stop(0.5)],
         quick=False),
    # penalty stiffness (exact as the reference; the penalty keys concern penalty only)
    Case("penalty-1e4", "penalty_factor 1e4 (c_p = 1e4 x the structure's contact stiffness), stop eps 0.5",
         [stop(0.5), "simulation.penalty_factor=1e4"], methods=("exact", "penalty"), t_quick=0.01, t_full=0.1),
    Case("penalty-1e6", "penalty_factor 1e6, stop eps 0.5", [stop(0.5), "simulation.penalty_factor=1e6"],
         methods=("exact", "penalty"), t_quick=0.01, t_full=0.1),
    Case("penalty-1e12N", "explicit penalty_stiffness 1e12 N/m, stop eps 0.5",
         [stop(0.5), "simulation.penalty_stiffness=1e12"], methods=("exact", "penalty"), t_full=0.1, quick=False),
    # refusals expected (is the message right?)
    Case("refuse-upper-eq-height", "upper_height = height (no lower sub-beam): must be refused",
         ["delamination.0.upper_height=0.02"], methods=("exact",), t_quick=0.01, t_full=0.01, expect="refused"),
    Case("refuse-thin", "a 1 um sub-beam (below the 1e-3 x height limit): must be refused",
         ["delamination.0.upper_height=0.019999"], methods=("exact",), t_quick=0.01, t_full=0.01, expect="refused"),
    Case("refuse-points-40el", "101 contact points on the shipped 40-element mesh: must be refused",
         ["delamination.0.contact_points=101"], methods=("exact",), t_quick=0.01, t_full=0.01, expect="refused"),
    Case("refuse-eps-1.5", "restitution 1.5: must be refused", ["delamination.0.restitution=1.5"],
         methods=("exact",), t_quick=0.01, t_full=0.01, expect="refused"),
    Case("refuse-stop-penetrated", "stop with negative clearance (starts penetrated)",
         [stop(0.5, clearance=-1e-4)], methods=("exact",), t_quick=0.01, t_full=0.01, expect="refused"),
]


# --------------------------------------------------------------------------- one run
def _child(case: Case, method: str, t_end: float, budget: float, conn) -> None:
    """Run one (case, method) and send its row through ``conn``; an interrupt at ``budget`` s."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

    def alarm(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGALRM, alarm)
    row: dict = {}
    warnings: list[str] = []
    wall0 = time.perf_counter()
    stage = "setup"
    try:
        signal.setitimer(signal.ITIMER_REAL, budget)
        from nsfem import load_scene
        from nsfem.errors import IntegrationError, NsfemError, SceneError
        from nsfem.simulate import run_scene

        try:
            scene = load_scene(None, overrides(case, t_end))
            stage = "run"
            result, system = run_scene(scene, method, warn=warnings.append)
            signal.setitimer(signal.ITIMER_REAL, 0)
            row["status"] = "completed" if result.completed else "timeout"
            if not result.completed:
                row["diagnosis"] = f"interrupted at the budget of {budget:g} s"
            row.update(_summary(result, system.contacts.mu))
            try:
                row["supercritical"] = _supercritical(scene, system)
            except Exception:  # a diagnostic only
                pass
        except IntegrationError as exc:
            signal.setitimer(signal.ITIMER_REAL, 0)
            row["status"] = "failed"
            row["diagnosis"] = str(exc).splitlines()[0]
            sysm = getattr(exc, "system", None)
            row.update(_summary(exc.result, None if sysm is None else sysm.contacts.mu))
        except SceneError as exc:
            row["status"], row["diagnosis"] = "refused", str(exc).splitlines()[0]
        except NsfemError as exc:
            row["status"], row["diagnosis"] = "setup-failed", str(exc).splitlines()[0]
    except KeyboardInterrupt:
        row["status"] = "timeout"
        row["diagnosis"] = f"interrupted at the budget of {budget:g} s during {stage} (before the integration)"
        row["t_reached"] = 0.0
    except Exception as exc:  # a bug: report it, with where it came from
        import traceback

        signal.setitimer(signal.ITIMER_REAL, 0)
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        row["status"] = "crashed"
        row["diagnosis"] = (f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''} "
                            f"({Path(tb.filename).name}:{tb.lineno})")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    row["wall_s"] = time.perf_counter() - wall0
    if warnings:
        row["warnings"] = " | ".join(w.splitlines()[0] for w in warnings)
    conn.send(row)
    conn.close()


def _summary(result, mu=None) -> dict:
    s = result.summary()
    state = np.asarray(result.state)
    if mu is not None and state.size:
        state = state[np.asarray(mu) > 0]  # stick/slip of the contacts with friction
    ev_t = np.array([e["t"] for e in result.events]) if result.events else np.zeros(0)
    out = {"t_reached": float(result.t_end), "events": s["events"], "impacts": s["impacts"],
           "energy": s["energy"], "min_gap_m": s["min_gap_m"], "max_gap_m": s["max_gap_m"],
           "closed_fraction": s["closed_fraction"],
           "stick_fraction": float((state == 1).any(axis=0).mean()) if state.size else 0.0,
           "slip_fraction": float((state == 2).any(axis=0).mean()) if state.size else 0.0,
           "max_normal_force_N": s["max_normal_force_N"],
           "integration_s": float(result.wall_s), "ndof": s["ndof"], "ndof_full": s["ndof_full"],
           "configurations": result.info.get("configurations"),
           "t": np.asarray(result.t).tolist(), "gap": np.asarray(result.gap).tolist()}
    if ev_t.size > 1:
        d = np.diff(ev_t)
        out["min_event_spacing_s"] = float(d.min())
        out["events_same_time"] = int(np.sum(d <= 1e-12 * max(1.0, float(ev_t[-1]))))
    q = np.asarray(result.q)
    if q.shape[1] > 1 and not q[:, -1].any() and q[:, -2].any():
        out["last_output_zero"] = True  # a known defect: see the findings in the module docstring
    if result.events:
        e = result.events[-1]
        out["last_event"] = f"t={e['t']:.6g} {','.join(e['kinds'])} {e.get('before', '')} -> {e.get('after', '')}"
    return out


def _supercritical(scene, system) -> str | None:
    from nsfem.analysis.campbell import divergence_speeds, supercritical_warning
    from nsfem.fem.rotating import rotor_operators

    red = system.info["reduction"]
    top = red.info.get("max_frequency_hz")
    if not (scene.rotation.speed_hz and top):
        return None
    div = divergence_speeds(rotor_operators(system.info["model"], red.T))
    return supercritical_warning(scene.rotation.speed_hz, div[div <= 0.5 * top])


#: every run samples its outputs at OUTPUT_DT (finer than the shipped 1 ms, so that gaps and
#: penetrations between impacts are seen); moreau keeps its shipped step (output_dt / 10 = 0.1 ms)
OUTPUT_DT = 1e-4
MOREAU_STEP = 1e-4


def overrides(case: Case, t_end: float) -> list[str]:
    extra = [f"simulation.t_end={t_end:g}"]
    if not any(o.startswith("simulation.output_dt") for o in case.overrides):
        extra.append(f"simulation.output_dt={min(OUTPUT_DT, t_end):g}")
    if not any(o.startswith("simulation.moreau_step") for o in case.overrides):
        extra.append(f"simulation.moreau_step={MOREAU_STEP:g}")
    return list(case.overrides) + extra


def reproduce(case: Case, method: str, t_end: float) -> str:
    sets = " ".join(f"--set {shlex.quote(o)}" for o in overrides(case, t_end))
    return f"python -m nsfem run --method {method} {sets} --out /tmp/nsfem-{case.name} --json"


def run_one(case: Case, method: str, t_end: float, budget: float, grace: float) -> dict:
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(case, method, t_end, budget, send), daemon=True)
    t0 = time.perf_counter()
    proc.start()
    send.close()
    row = None
    if recv.poll(budget + grace):
        try:
            row = recv.recv()
        except EOFError:
            row = None
    if row is None:
        if proc.is_alive():
            os.kill(proc.pid, signal.SIGKILL)
            row = {"status": "killed",
                   "diagnosis": f"did not stop within {grace:g} s of the interrupt at {budget:g} s"}
        else:
            proc.join(1.0)
            row = {"status": "crashed", "diagnosis": f"the worker died (exit code {proc.exitcode})"}
        row["wall_s"] = time.perf_counter() - t0
    proc.join(5.0)
    recv.close()
    return {"case": case.name, "method": method, "t_end": t_end, **row}


# --------------------------------------------------------------------------- checks
def agreement(rows: list[dict]) -> None:
    """gap_diff of every completed row against exact (or rk) of the same case."""
    for r in rows:
        r.pop("reference", None)
    by_case: dict[str, list[dict]] = {}
    for r in rows:
        by_case.setdefault(r["case"], []).append(r)
    for case_rows in by_case.values():
        done = {r["method"]: r for r in case_rows if r["status"] == "completed" and r.get("gap")}
        ref_name = "exact" if "exact" in done else ("rk" if "rk" in done else None)
        if ref_name is None:
            continue
        ref = done[ref_name]
        g_ref = np.asarray(ref["gap"])
        scale = float(np.abs(g_ref[:, :-1]).max()) if g_ref.shape[-1] > 1 else 0.0
        for r in case_rows:
            if r is ref or r["status"] != "completed" or not r.get("gap"):
                continue
            g = np.asarray(r["gap"])
            if g.shape != g_ref.shape or scale == 0.0:
                continue
            # the sample at t_end is left out: exact/rk may leave it at zero (last_output_zero)
            r["gap_diff_m"] = float(np.abs(g[:, :-1] - g_ref[:, :-1]).max())
            r["gap_diff"] = r["gap_diff_m"] / scale
            r["reference"] = ref_name


#: a disagreement is flagged above 10 % of the reference's largest gap and above this [m]
DISAGREE_M = 1e-8


def flag(r: dict, expect: str = "completed") -> str:
    out = []
    if r["status"] != expect:
        out.append(r["status"])
    ev = r["method"] in ("exact", "rk")
    if ev and r["status"] == "completed" and r.get("energy") is not None and r["energy"] > 1e-6:
        out.append("energy")
    if ev and r.get("min_gap_m") is not None and r["min_gap_m"] < -1e-9:
        out.append("penetration")
    if r.get("t_reached") and r.get("events", 0) / r["t_reached"] > 1e5:
        out.append("event-rate")
    if r.get("last_output_zero"):
        out.append("last-output-zero")
    if r.get("gap_diff") is not None and r["gap_diff"] > 0.1 and r["gap_diff_m"] > DISAGREE_M:
        out.append("disagree")
    return ",".join(out)


# --------------------------------------------------------------------------- output
def _fmt(x, spec: str) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return format(x, spec)


def code_version() -> dict:
    """The commit the runs used, and whether nsfem/ had uncommitted changes (the repo is shared)."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--short", "nsfem"], cwd=root, capture_output=True, text=True,
                               timeout=10).stdout.split()[1::2]
    except (OSError, subprocess.SubprocessError):
        return {}
    return {"commit": head, "uncommitted_nsfem_files": dirty}


def markdown(rows: list[dict], cases: dict[str, Case]) -> str:
    head = ("| case | method | status | t reached / t_end [s] | events | impacts | energy | min gap [m] | "
            "max gap [m] | closed | stick | slip | gap diff | wall [s] | flags |")
    lines = [head, "|" + "---|" * 15]
    for r in rows:
        t = f"{_fmt(r.get('t_reached'), '.4g')} / {r['t_end']:g}"
        lines.append("| " + " | ".join([
            r["case"], r["method"], r["status"], t, _fmt(r.get("events"), "d"), _fmt(r.get("impacts"), "d"),
            _fmt(r.get("energy"), ".1e"), _fmt(r.get("min_gap_m"), ".2e"),
            _fmt(r.get("max_gap_m"), ".2e"), _fmt(r.get("closed_fraction"), ".2f"),
            _fmt(r.get("stick_fraction"), ".2f"), _fmt(r.get("slip_fraction"), ".2f"),
            _fmt(r.get("gap_diff"), ".1e"), _fmt(r.get("wall_s"), ".2f"), r.get("flags", "")]) + " |")
    notes = [r for r in rows if r.get("diagnosis") and r["status"] != "completed"]
    if notes:
        lines.append("")
        for r in notes:
            lines.append(f"- {r['case']} / {r['method']}: {r['status']}: {r['diagnosis']}")
    return "\n".join(lines)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the quick subset, short t_end (< 5 min on 2 cores)")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    ap.add_argument("--case", nargs="*", default=None, help="run only these cases (names, see --list)")
    ap.add_argument("--methods", default=None, help="comma-separated subset of exact,rk,penalty,moreau")
    ap.add_argument("--budget", type=float, default=None, help="wall-time budget per run [s] (quick 8, full 30)")
    ap.add_argument("--t-end", type=float, default=None, help="override every case's t_end")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "extremes"))
    args = ap.parse_args(argv)
    if args.list:
        for c in CASES:
            print(f"{c.name:24s} {'quick' if c.quick else 'full ':5s} {','.join(c.methods):24s} {c.description}")
        return {}
    names = {c.name: c for c in CASES}
    if args.case:
        unknown = [n for n in args.case if n not in names]
        if unknown:
            ap.error(f"unknown case(s) {unknown}; see --list")
        cases = [names[n] for n in args.case]
    else:
        cases = [c for c in CASES if c.quick or not args.quick]
    wanted = set(args.methods.split(",")) if args.methods else set(ALL)
    budget = args.budget or (8.0 if args.quick else 30.0)
    import nsfem.simulate  # noqa: F401  (imported once here, shared by the forked workers)

    rows = []
    t_start = time.perf_counter()
    for c in cases:
        t_end = args.t_end or (c.t_quick if args.quick else c.t_full)
        for method in [m for m in c.methods if m in wanted]:
            b = budget * c.budget_factor
            r = run_one(c, method, t_end, b, grace=max(10.0, 0.5 * b))
            r["reproduce"] = reproduce(c, method, t_end)
            rows.append(r)
            if not args.json:
                print(f"  {c.name:24s} {method:8s} {r['status']:12s} {r.get('wall_s', 0):7.2f} s  "
                      f"events {r.get('events', '-')}  {r.get('diagnosis', '')}", flush=True)
    total = time.perf_counter() - t_start
    agreement(rows)
    for r in rows:
        r["flags"] = flag(r, names[r["case"]].expect)
        r["description"] = names[r["case"]].description
    table_rows = [{k: v for k, v in r.items() if k not in ("t", "gap")} for r in rows]
    status = {}
    for r in rows:
        status[r["status"]] = status.get(r["status"], 0) + 1
    summary = {"runs": len(rows), "status": status, "flagged": [f"{r['case']}/{r['method']}: {r['flags']}"
                                                               for r in rows if r["flags"]],
               "total_wall_s": total, "budget_per_run_s": budget, "quick": args.quick}
    payload = {"rows": table_rows, "summary": summary, "machine": {**machine(), **code_version()},
               "cases": {c.name: {"description": c.description, "overrides": c.overrides,
                                  "methods": list(c.methods)} for c in cases}}
    name = "extremes_quick" if args.quick else "extremes"
    if not args.case and not args.methods:
        write_outputs(Path(args.out), name, table_rows, payload)
    else:
        write_outputs(Path(args.out), name + "_partial", table_rows, payload)
    table = markdown(table_rows, names)
    (Path(args.out) / f"{name if not (args.case or args.methods) else name + '_partial'}.md").write_text(
        table + f"\n\n{len(rows)} runs in {total:.1f} s; status {status}\n")
    if args.json:
        print(json.dumps({"summary": summary, "rows": table_rows, "machine": payload["machine"]}))
    else:
        print(table)
        print(f"\n{len(rows)} runs in {total:.1f} s; status {status}")
    return payload


if __name__ == "__main__":
    main()
