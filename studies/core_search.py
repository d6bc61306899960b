"""The compiled event search (nsfem/integrate/core/_search.pyx) against its pure-Python reference.

Side by side in one process (both paths through ``core.reference()``, best of ``--repeat``, CPU time
of the process: the machines these run on are shared): the search (the time spent in
``events.first_event``, per event), the compiled call (its set-up and loop since the set-up moved into
it; for the reference, its search less what the compiled path spends outside the call) and whole runs
of the stop scene (studies/work_precision.py's: 282 events), the shipped scene (1 s), retainer_drop's
first 20 ms (65 events on the divided-difference path: a rigid drop), the crack and the rub as shipped,
in ms per event (``--scenes`` picks some); which
fraction of the searches runs compiled and why the others fall back to Python; and where the
compiled run's time per event goes (cProfile, by function). Run it with OPENBLAS_NUM_THREADS=1.

Writes ``core_search.json`` and ``core_search.csv`` into ``--out`` (default studies/out/core_search)
and, with ``--json``, prints the JSON object.

    python studies/core_search.py [--quick] [--json]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time
from pathlib import Path

from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import core, event_driven, events
from nsfem.simulate import run_scene

#: (scene, overrides) of the runs measured
SCENES = {
    "stop": ("default", ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]', "simulation.t_end=0.05"]),
    "shipped": ("default", []),
    "retainer_drop": ("retainer_drop", ["simulation.t_end=0.02"]),
    "crack": ("crack", []),
    "rub": ("rub", []),
}


class Watch:
    """Time spent in events.first_event, and which searches run compiled (the others: why not)."""

    def __init__(self):
        self.search_s, self.loop_s, self.calls, self.compiled, self.reasons = 0.0, 0.0, 0, 0, {}

    def __enter__(self):
        self._first, self._compiled = event_driven.first_event, events._compiled_search

        def first_event(phase, rows, *args, **kw):
            t0 = time.process_time()
            try:
                return self._first(phase, rows, *args, **kw)
            finally:
                self.search_s += time.process_time() - t0
                self.calls += 1
                if core.compiled("search") is not None:
                    why = _fallback(phase) if rows.size else "no event rows"
                    if why is not None:
                        self.reasons[why] = self.reasons.get(why, 0) + 1

        def compiled(*args, **kw):
            self.compiled += 1
            t0 = time.process_time()
            try:
                return self._compiled(*args, **kw)
            finally:
                self.loop_s += time.process_time() - t0

        event_driven.first_event, events._compiled_search = first_event, compiled
        return self

    def __exit__(self, *exc):
        event_driven.first_event, events._compiled_search = self._first, self._compiled


def _fallback(phase) -> str | None:
    """Why a search stays on the Python path (None: it can run compiled, unless its bound needs the
    local one, counted as the rest)."""
    if phase.config.fastest_rate() == 0.0 and phase.w == 0.0:
        return "polynomial (rigid-body phase)"
    if phase._modal is None:
        return "matrix exponential"
    return None


def measure(name: str, repeat: int) -> dict:
    scene_name, overrides = SCENES[name]
    out = {"scene": name}
    for path in ("compiled", "python"):
        best = None
        for _ in range(repeat):
            scene = load_scene(scene_name, overrides)
            with Watch() as w:
                t0 = time.process_time()
                if path == "python":
                    with core.reference():
                        res = run_scene(scene, "exact")[0]
                else:
                    res = run_scene(scene, "exact")[0]
                wall = time.process_time() - t0
            if best is None or wall < best[0]:
                best = (wall, w, len(res.events))
        wall, w, n = best
        out[path] = {"events": n, "cpu_s": wall, "ms_per_event": 1e3 * wall / max(n, 1),
                     "search_ms_per_event": 1e3 * w.search_s / max(n, 1), "searches": w.calls,
                     "loop_ms_per_event": 1e3 * w.loop_s / max(n, 1)}
        if path == "compiled":
            fell = sum(w.reasons.values())
            out["searches_compiled"] = w.compiled
            out["searches_fallback"] = {k: v for k, v in w.reasons.items()}
            out["searches_fallback_other"] = max(w.calls - w.compiled - fell, 0)
    c, p = out["compiled"], out["python"]
    # the reference's share of what the compiled call does: its search less what the compiled path spends outside
    # the call (since the set-up moved into it, that is the Python around the call)
    p["loop_ms_per_event"] = p["search_ms_per_event"] - (c["search_ms_per_event"] - c["loop_ms_per_event"])
    out["speedup_run"] = p["cpu_s"] / c["cpu_s"]
    out["speedup_search"] = p["search_ms_per_event"] / c["search_ms_per_event"]
    out["speedup_loop"] = p["loop_ms_per_event"] / c["loop_ms_per_event"]
    return out


#: every shipped scene over a window with events (tests/test_core_equivalence.py's cases): which
#: searches fall back to Python
WINDOWS = {
    "default": ("default", ["simulation.t_end=0.3"]),
    "crack": ("crack", ["simulation.t_end=0.05"]),
    "critical_speed": ("critical_speed", ["simulation.t_end=0.05"]),
    "ross_example": ("ross_example", ["simulation.t_end=0.05"]),
    "rub": ("rub", ["simulation.t_end=0.05"]),
    "retainer_drop": ("retainer_drop", ["simulation.t_end=0.02"]),
}


def fallbacks() -> list:
    """Per shipped scene: the searches, how many ran compiled, and why the others did not."""
    rows = []
    for name, (scene_name, overrides) in WINDOWS.items():
        with Watch() as w:
            res = run_scene(load_scene(scene_name, overrides), "exact")[0]
        fell = sum(w.reasons.values())
        rows.append({"scene": name, "events": len(res.events), "searches": w.calls, "compiled": w.compiled,
                     **w.reasons, "local bound": max(w.calls - w.compiled - fell, 0)})
    return rows


def profile(name: str, top: int = 15) -> list:
    """The compiled run's time per event by function (cProfile, tottime), the largest first."""
    scene_name, overrides = SCENES[name]
    scene = load_scene(scene_name, overrides)
    prof = cProfile.Profile()
    prof.enable()
    res = run_scene(scene, "exact")[0]
    prof.disable()
    n = max(len(res.events), 1)
    stats = pstats.Stats(prof).stats
    rows = []
    for (file, line, fn), (_, ncalls, tt, ct, _) in stats.items():
        rows.append({"function": f"{Path(file).name}:{line}({fn})", "calls_per_event": ncalls / n,
                     "tottime_ms_per_event": 1e3 * tt / n, "cumtime_ms_per_event": 1e3 * ct / n})
    rows.sort(key=lambda r: -r["tottime_ms_per_event"])
    return rows[:top]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the stop scene only, best of 2")
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--scenes", nargs="+", choices=list(SCENES), default=None, help="the scenes measured (default: all)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "core_search"))
    args = ap.parse_args(argv)
    if core.compiled("search") is None:
        raise SystemExit("core_search: the compiled search is not built (python setup.py build_ext --inplace)")
    repeat = args.repeat or (2 if args.quick else 3)
    names = args.scenes or (["stop"] if args.quick else list(SCENES))
    rows = [measure(name, repeat) for name in names]
    payload = {"machine": machine(), "core": core.name(), "cases": rows, "profile_stop": profile("stop"),
               "fallbacks": [] if args.quick else fallbacks()}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    flat = [{"scene": r["scene"], **{f"{p}_{k}": v for p in ("compiled", "python") for k, v in r[p].items()},
             "speedup_run": r["speedup_run"], "speedup_search": r["speedup_search"],
             "speedup_loop": r["speedup_loop"]} for r in rows]
    write_outputs(out, "core_search", flat, payload)
    if args.json:
        print(json.dumps(payload))
    else:
        for r in rows:
            c, p = r["compiled"], r["python"]
            print(f"{r['scene']:8s} {c['events']:4d} events  run {p['ms_per_event']:.3f} -> {c['ms_per_event']:.3f} "
                  f"ms/event ({r['speedup_run']:.2f}x)  search {p['search_ms_per_event']:.3f} -> "
                  f"{c['search_ms_per_event']:.3f} ms/event ({r['speedup_search']:.2f}x)  the compiled call "
                  f"{p['loop_ms_per_event']:.3f} -> {c['loop_ms_per_event']:.3f} ms/event ({r['speedup_loop']:.2f}x)  "
                  f"searches {c['searches']}: "
                  f"compiled {r['searches_compiled']}, fallback {r['searches_fallback']} + "
                  f"{r['searches_fallback_other']} other")
        for r in payload["fallbacks"]:
            print(f"{r['scene']:15s} {r['events']:4d} events, {r['searches']:4d} searches: compiled {r['compiled']}, "
                  + ", ".join(f"{k} {v}" for k, v in r.items() if k not in ("scene", "events", "searches", "compiled")))
        print("compiled stop run, per event by function (tottime ms):")
        for r in payload["profile_stop"]:
            print(f"  {r['tottime_ms_per_event']:7.4f}  {r['calls_per_event']:7.1f} calls  {r['function']}")
        print(f"wrote {out}")
    return payload


if __name__ == "__main__":
    main()
