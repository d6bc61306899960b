"""An event's resolution and the run loop's bookkeeping (core part "resolve", issue 33) against the Python reference.

Side by side in one process, both paths through ``core.reference()``, best of ``--repeat`` runs in CPU
time of the process (the machine is shared), OPENBLAS_NUM_THREADS=1:

- ``resolve`` alone: every call of a run replayed on its captured inputs (each on a copy of the memory
  it met), us per call: the reference, the compiled core without its impact path (``_impact_fast``
  handing every event back) and with it;
- the share of resolve calls the compiled impact path takes (an impact of frictionless contacts after
  which every contact is open) on the stop scene and every shipped scene (the default over 1 s, the others
  over 0.3 s, retainer_drop 0.05 s), and the calls it handed back by the full path's outcome;
- end to end: the stop scene (the shipped shaft with a stop 0.2 mm under midspan, restitution 0.5,
  0.05 s: 282 events), the same with friction 0.3 on the stop (309 events) and the shipped scene over 1 s,
  ms per event both ways (and the compiled core without its impact path, the stop scenes);
- the stop scene's time per event by part of the event loop (the loop's own Python is what is left of
  the run's time after the parts named), both ways;
- where the compiled run's time per event goes: cProfile of the stop scene (CPU time), by function (tottime).

    OPENBLAS_NUM_THREADS=1 python studies/core_resolve.py [--quick] [--json] [--out DIR]

``--quick``: best of 3 (default 5) and the shipped scene over 0.3 s. Writes core_resolve.json/.csv into
studies/out/core_resolve.
"""

from __future__ import annotations

import argparse
import copy
import functools
import json
import time
from pathlib import Path

from core_phase import STOP, best, end_to_end, profile
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import core
from nsfem.integrate import event_driven as ed
from nsfem.integrate import guard
from nsfem.integrate import transitions as tr
from nsfem.simulate import run_scene

#: the memory's caches of its contact set and system (immutable): shared by the replay's copies
_CACHES = ("_abs", "_abs_system", "_slip", "_kernel", "_impact", "lcp_cache")


def _copy(memory: tr.Memory) -> tr.Memory:
    """A copy of the memory's state (scales, impacts) sharing its caches."""
    saved = {f: getattr(memory, f) for f in _CACHES if hasattr(memory, f)}   # (an older checkout has fewer)
    for f in saved:
        setattr(memory, f, None)
    try:
        out = copy.deepcopy(memory)
    finally:
        for f, v in saved.items():
            setattr(memory, f, v)
    for f, v in saved.items():
        setattr(out, f, v)
    return out


def resolve_calls(scene, repeat: int) -> dict:
    """us per resolve call, both paths, on the calls of one run."""
    calls, orig = [], ed.resolve

    def capture(*args, **kw):
        calls.append((args, kw, _copy(args[6])))
        return orig(*args, **kw)

    ed.resolve = capture
    try:
        run_scene(scene, "exact")
    finally:
        ed.resolve = orig

    def replay():
        for args, kw, memory in calls:
            args = list(args)
            args[6] = _copy(memory)
            tr.resolve(*args, **kw)

    def copies():   # the replay's own cost (the copies), taken off
        for _, _, memory in calls:
            _copy(memory)

    base = best(copies, repeat)
    with core.reference():
        ref = best(replay, repeat) - base
    comp = best(replay, repeat) - base
    fast = getattr(tr, "_impact_fast", None)   # (an older checkout has none)
    whole = comp
    if fast is not None:
        tr._impact_fast = lambda *a, **k: None
        try:
            whole = best(replay, repeat) - base
        finally:
            tr._impact_fast = fast
    n = len(calls)
    return {"calls": n, "python_us": 1e6 * ref / n, "compiled_without_impact_path_us": 1e6 * whole / n,
            "compiled_us": 1e6 * comp / n, "speedup": ref / comp}


#: scenes whose resolve calls are counted: the stop scene and every shipped scene
SCENES = {"stop": ("default", STOP), "default": ("default", ["simulation.t_end=1.0"]),
          "crack": ("crack", ["simulation.t_end=0.3"]), "critical_speed": ("critical_speed", ["simulation.t_end=0.3"]),
          "ross_example": ("ross_example", ["simulation.t_end=0.3"]), "rub": ("rub", ["simulation.t_end=0.3"]),
          "retainer_drop": ("retainer_drop", ["simulation.t_end=0.05"])}


def without_impact_path(scene, repeat: int) -> float:
    """The compiled run's ms per event with the impact path handing every event back (same process)."""
    fast = tr._impact_fast
    tr._impact_fast = lambda *a, **k: None
    try:
        n = max(len(run_scene(scene, "exact")[0].events), 1)
        return 1e3 * best(lambda: run_scene(scene, "exact"), repeat) / n
    finally:
        tr._impact_fast = fast


def impact_path_share() -> dict:
    """Per scene: resolve calls, how many the compiled impact path took, and why it handed the others back
    (the full path's outcome: an impact with a contact closed after it, a transition without impact...)."""
    out = {}
    for name, (scene, over) in SCENES.items():
        took, calls, orig, fast = [], [], ed.resolve, tr._impact_fast

        def spy(*a, **k):
            r = fast(*a, **k)
            took.append(r is not None)
            return r

        def count(*a, **k):
            n = len(took)
            res = orig(*a, **k)
            if len(took) == n:   # the path was not asked (the first call: no scales yet)
                took.append(False)
            calls.append(("impact" if res[2] else "no impact") + (", closed after" if res[0].closed else ""))
            return res

        ed.resolve, tr._impact_fast = count, spy
        try:
            run_scene(load_scene(scene, over), "exact")
        finally:
            ed.resolve, tr._impact_fast = orig, fast
        back: dict = {}
        for t, c in zip(took, calls):
            if not t:
                back[c] = back.get(c, 0) + 1
        out[name] = {"calls": len(calls), "impact_path": sum(took), "share": sum(took) / max(len(calls), 1),
                     "handed_back": back}
    return out


#: the parts of an event timed by wrappers: (module, attribute, label)
PARTS = ((ed.Exact, "_advance", "search"), (ed, "resolve", "resolve"), (ed.EventDriven, "_phase", "phase set-up"),
         (ed.EventDriven, "_energy", "energy"), (ed, "event_rows", "event rows"), (ed, "check_phase", "check_phase"),
         (ed, "check_state", "check_state"), (guard.EventGuard, "record", "guard.record"),
         (ed, "hold_degenerate", "hold_degenerate"), (ed.EventDriven, "_outputs", "outputs"),
         (ed.EventDriven, "run", "integration"))


def by_part(scene, repeat: int) -> dict:
    """ms per event by part of the loop, both paths (CPU time; each part's best over the runs)."""
    spent: dict = {}
    saved = [(owner, name, getattr(owner, name)) for owner, name, _ in PARTS]

    def timed(fn, label):
        @functools.wraps(fn)
        def wrapper(*a, **k):
            t = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                spent[label] = spent.get(label, 0.0) + time.process_time() - t
        return wrapper

    out = {}
    try:
        for owner, name, label in PARTS:
            setattr(owner, name, timed(getattr(owner, name), label))
        for path in ("python", "compiled"):
            best_run = None
            for _ in range(repeat):
                spent.clear()
                t = time.process_time()
                if path == "python":
                    with core.reference():
                        res = run_scene(scene, "exact")[0]
                else:
                    res = run_scene(scene, "exact")[0]
                total = time.process_time() - t
                run = dict(spent, total=total)
                if best_run is None or run["integration"] < best_run["integration"]:
                    best_run = run
            n = max(len(res.events), 1)
            # the loop's own Python: the integration's time (EventDriven.run) less the parts'
            loop = best_run["integration"] - sum(v for k, v in best_run.items() if k not in ("total", "integration"))
            out[path] = {**{k: 1e3 * v / n for k, v in best_run.items() if k not in ("total", "integration")},
                         "loop": 1e3 * loop / n, "integration": 1e3 * best_run["integration"] / n}
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="best of 3, the shipped scene over 0.3 s")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=None, help="runs per timing (best of them)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "core_resolve"))
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 5)
    if not any(core.compiled(part) is not None for part in core.PARTS):   # (a checkout before "resolve" runs too)
        raise SystemExit(f"core_resolve: no compiled part is active ({core.name()})")
    stop = load_scene("default", STOP)
    stop_mu = load_scene("default", [STOP[0].replace("restitution=0.5", "restitution=0.5, friction=0.3"), *STOP[1:]])
    shipped = load_scene("default", [f"simulation.t_end={0.3 if args.quick else 1.0}"])
    payload = {"machine": machine(), "core": core.name(), "repeat": repeat,
               "resolve_stop": resolve_calls(stop, repeat), "resolve_stop_friction": resolve_calls(stop_mu, repeat),
               "impact_path": impact_path_share(),
               "parts_stop": by_part(stop, repeat),
               "stop": {**end_to_end(stop, repeat),
                        "compiled_without_impact_path_ms_per_event": without_impact_path(stop, repeat)},
               "stop_friction": {**end_to_end(stop_mu, repeat),
                                 "compiled_without_impact_path_ms_per_event": without_impact_path(stop_mu, repeat)},
               "shipped": end_to_end(shipped, repeat),
               "profile_stop_compiled": profile(stop)}
    rows = [{"case": "resolve (replayed)", **payload["resolve_stop"]},
            {"case": "resolve (replayed), friction", **payload["resolve_stop_friction"]}]
    rows += [{"case": name, **payload[name]} for name in ("stop", "stop_friction", "shipped")]
    rows += [{"case": f"impact path {k}", **{kk: vv for kk, vv in v.items() if kk != "handed_back"},
              "handed_back": json.dumps(v["handed_back"])} for k, v in payload["impact_path"].items()]
    parts = payload["parts_stop"]
    rows += [{"case": f"stop part {k}", "python_ms_per_event": v, "compiled_ms_per_event": parts["compiled"][k]}
             for k, v in parts["python"].items()]
    write_outputs(Path(args.out), "core_resolve", rows, payload)
    if args.json:
        print(json.dumps(payload))
        return
    for r in rows:
        print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()})
    for p in payload["profile_stop_compiled"]:
        print(f"{p['tottime_ms_per_event']:8.4f} {p['cumtime_ms_per_event']:8.4f} {p['calls']:7d} {p['function']}")


if __name__ == "__main__":
    main()
