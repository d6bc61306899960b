"""The exact method's per-event path outside the search and the resolve (issue 33, "fastloop"): the phase's
set-up in one compiled call (``PhaseSetup.start``: phase_start and phase_modal) and the state at the event in
one (``PhaseSetup.state``), against the pure-Python reference.

Side by side in one process (both paths, the reference by ``core.reference()``), best of ``--repeat`` runs in
CPU time of the process (the machine is shared), OPENBLAS_NUM_THREADS=1:

- per phase, replayed on every phase of the stop scene's run: the set-up (``Phase(...)``) and the state (q, q')
  at the phase's end (``Phase.state_at``; the loop's ``q_map() @ xi``, ``v_map() @ xi`` before), each way;
- end to end, ms per event both ways: the stop scene (the shipped shaft with a stop 0.2 mm under midspan,
  0.05 s: 282 events), the shipped scene over 1 s, crack (1 s) and rub (as shipped, 2 s);
- where the compiled stop scene's time per event goes: cProfile (CPU time), by function (tottime).

    OPENBLAS_NUM_THREADS=1 python studies/core_loop.py [--quick] [--json] [--out DIR]

Writes core_loop.json/.csv into studies/out/core_loop.
"""

from __future__ import annotations

import argparse
import json
from contextlib import nullcontext
from pathlib import Path

from core_phase import STOP, best, end_to_end, profile
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import core
from nsfem.integrate import event_driven as ed_mod
from nsfem.integrate.configuration import Phase
from nsfem.simulate import run_scene


def capture(scene) -> list:
    """(configuration, t0, q0, q0', g0, t1) of every phase of the run that reached its end (t1)."""
    seen, orig = [], ed_mod.EventDriven._phase

    def spy(self, mode, t, q, v):
        phase = orig(self, mode, t, q, v)
        seen.append([phase.config, t, q.copy(), v.copy(), phase.g0.copy(), None])
        return phase

    ed_mod.EventDriven._phase = spy
    try:
        res, _ = run_scene(scene, "exact")
    finally:
        ed_mod.EventDriven._phase = orig
    # a phase ends where the next one starts (held-degenerate probes start at the same time: dropped)
    for a, b in zip(seen, seen[1:]):
        a[5] = b[1]
    a = seen[-1]
    a[5] = float(res.t[-1]) if len(res.t) else a[1]
    return [tuple(s) for s in seen if s[5] > s[1]]


def per_phase(calls: list, repeat: int) -> dict:
    """µs per phase of the set-up and of the state at its end, compiled and reference: the two timed in turn,
    ``repeat`` times each (best of them), so that both see the same heap (a fresh run's first set-ups, with the
    allocator's pages still to be touched, take up to twice as long either way)."""
    def build():
        return [Phase(cfg, t0, q, v, g0) for cfg, t0, q, v, g0, _ in calls]

    def states(phases):
        return [p.state_at(t1) for p, (*_, t1) in zip(phases, calls)]

    times = {label: {"setup_us": [], "state_us": []} for label in ("compiled", "python")}
    for _ in range(repeat):
        for label in times:
            with (core.reference() if label == "python" else nullcontext()):
                times[label]["setup_us"].append(best(build, 1))
                phases = build()
                times[label]["state_us"].append(best(lambda: states(phases), 1))
    return {label: {key: 1e6 * min(vals) / len(calls) for key, vals in parts.items()}
            for label, parts in times.items()}


def per_event(scene, repeat: int) -> dict:
    """µs per call, compiled and reference in turn (best of ``repeat``), of the loop's other per-phase steps on a
    run's own calls: the event rows (``events.event_rows``), ``guard.check_phase`` and the energy
    (``EventDriven._energy``, its work integrals into a scratch dict)."""
    seen = {"rows": [], "check": [], "energy": []}
    spied = [(ed_mod, "event_rows", "rows"), (ed_mod, "check_phase", "check"), (ed_mod.EventDriven, "_energy", "energy")]
    origs = [getattr(obj, name) for obj, name, _ in spied]

    def spy(orig, key):
        def wrapped(*args, **kw):
            seen[key].append((args, kw))
            return orig(*args, **kw)
        return wrapped

    for (obj, name, key), orig in zip(spied, origs):
        setattr(obj, name, spy(orig, key))
    try:
        run_scene(scene, "exact")
    finally:
        for (obj, name, _), orig in zip(spied, origs):
            setattr(obj, name, orig)
    fns = dict(zip(seen, origs))

    def replay(key):
        fn, calls = fns[key], seen[key]
        if key == "energy":     # (a scratch dict: the run's own is not touched)
            return lambda: [fn(*a[:9], {k: 0.0 for k in a[9]}, *a[10:], **kw) for a, kw in calls]
        return lambda: [fn(*a, **kw) for a, kw in calls]

    times = {label: {key: [] for key in seen} for label in ("compiled", "python")}
    for _ in range(repeat):
        for label in times:
            with (core.reference() if label == "python" else nullcontext()):
                for key in seen:
                    times[label][key].append(best(replay(key), 1))
    return {label: {f"{key}_us": 1e6 * min(vals) / max(len(seen[key]), 1) for key, vals in parts.items()}
            for label, parts in times.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="best of 3, the shipped scene, crack and rub over 0.3 s")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=None, help="runs per timing (best of them)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "core_loop"))
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 5)
    if core.compiled("phase") is None:
        raise SystemExit(f"core_loop: the compiled part 'phase' is not active ({core.name()})")
    short = ["simulation.t_end=0.3"] if args.quick else []
    scenes = {"stop": load_scene("default", STOP),
              "shipped": load_scene("default", ["simulation.t_end=1.0"] + short),
              "crack": load_scene("crack", short), "rub": load_scene("rub", short)}
    calls = capture(scenes["stop"])
    payload = {"machine": machine(), "core": core.name(), "repeat": repeat,
               "per_phase_stop": {"phases": len(calls), **per_phase(calls, repeat)},
               "per_call_stop": per_event(scenes["stop"], repeat),
               "end_to_end": {name: end_to_end(scene, repeat) for name, scene in scenes.items()},
               "profile_stop": profile(scenes["stop"], 30)}
    rows = [{"case": name, **vals} for name, vals in payload["end_to_end"].items()]
    write_outputs(Path(args.out), "core_loop", rows, payload)
    if args.json:
        print(json.dumps(payload))
        return
    pp = payload["per_phase_stop"]
    print(f"per phase (stop scene, {pp['phases']} phases): set-up {pp['compiled']['setup_us']:.1f} µs compiled, "
          f"{pp['python']['setup_us']:.1f} µs Python; state at the end {pp['compiled']['state_us']:.2f} µs compiled, "
          f"{pp['python']['state_us']:.2f} µs Python")
    pc = payload["per_call_stop"]
    print("per call (stop scene): " + ", ".join(f"{key[:-3]} {pc['compiled'][key]:.1f} µs compiled, "
                                                f"{pc['python'][key]:.1f} µs Python" for key in pc["compiled"]))
    for name, e in payload["end_to_end"].items():
        print(f"{name:8s} {e['events']:5d} events: {e['python_ms_per_event']:.3f} ms/event Python, "
              f"{e['compiled_ms_per_event']:.3f} compiled ({e['speedup']:.2f}x)")
    print("compiled stop scene, ms per event by function (own time, cumulative):")
    for row in payload["profile_stop"]:
        print(f"  {row['tottime_ms_per_event']:.4f} {row['cumtime_ms_per_event']:.4f} {row['calls']:6d} "
              f"{row['function']}")


if __name__ == "__main__":
    main()
