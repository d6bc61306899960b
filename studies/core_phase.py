"""The compiled phase set-up and closed-form energy (core part "phase", issue 33) against the Python reference.

Side by side in one process, both paths through ``core.reference()``, best of ``--repeat`` runs in CPU
time of the process (the machine is shared), OPENBLAS_NUM_THREADS=1:

- the kernels alone: every phase set-up (``Phase(...)``) and every energy call (``EventDriven._energy``)
  of a run, replayed on the inputs captured from it, and the state at one time (``Phase._xi_at``, the
  root refinement's evaluation) at four times per phase;
- end to end: the stop scene (the shipped shaft with a stop 0.2 mm under midspan, restitution 0.5,
  0.05 s: 282 events) and the shipped scene over 1 s, ms per event both ways;
- where the compiled run's time per event goes: cProfile of the stop scene (CPU time), by function (tottime).

    OPENBLAS_NUM_THREADS=1 python studies/core_phase.py [--quick] [--json] [--out DIR]

``--quick``: best of 3 (default 5) and the shipped scene over 0.3 s. Writes core_phase.json/.csv into
studies/out/core_phase.
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
from nsfem.integrate import configuration as cfg_mod
from nsfem.integrate import core
from nsfem.integrate import event_driven as ed_mod
from nsfem.simulate import run_scene

STOP = ["obstacle=[{x=0.5, normal=\"-z\", clearance=2e-4, restitution=0.5}]", "simulation.t_end=0.05"]


def best(fn, repeat: int) -> float:
    """The shortest of ``repeat`` runs of fn, in CPU seconds of this process (time.process_time: on a
    shared machine the wall clock also counts the other processes' turns; one BLAS thread)."""
    times = []
    for _ in range(repeat):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return min(times)


def capture(scene):
    """The run, and the arguments of every phase set-up and energy call in it."""
    phases, energies = [], []
    init, energy = cfg_mod.Phase.__init__, ed_mod.EventDriven._energy

    def rec_init(self, config, t0, q0, v0, g0):
        phases.append((config, t0, q0.copy(), v0.copy(), g0.copy()))
        init(self, config, t0, q0, v0, g0)

    def rec_energy(self, phase, mode, xi_fun, t0, t1, K, P, D, totals, ends=None):
        energies.append((self, phase, mode, xi_fun, t0, t1, K, P, D, dict(totals), ends))
        return energy(self, phase, mode, xi_fun, t0, t1, K, P, D, totals, ends)

    cfg_mod.Phase.__init__, ed_mod.EventDriven._energy = rec_init, rec_energy
    try:
        res = run_scene(scene, "exact")[0]
    finally:
        cfg_mod.Phase.__init__, ed_mod.EventDriven._energy = init, energy
    return res, phases, energies


def kernels(scene, repeat: int) -> dict:
    """us per phase set-up and per energy call, both paths, on the inputs of one run."""
    res, phases, energies = capture(scene)

    def setups():
        for args in phases:
            cfg_mod.Phase(*args)

    def energy_calls():
        for e in energies:
            e[0]._energy(*e[1:9], dict(e[9]), e[10])

    with core.reference():
        ref_phases = [cfg_mod.Phase(*args) for args in phases]
    comp_phases = [cfg_mod.Phase(*args) for args in phases]
    times = [(p.t0 + 1e-5 * (k + 1)) for p in ref_phases for k in range(4)]

    def states():   # the root refinement's evaluations: four times per phase, each on its own path's phase
        for i, t in enumerate(times):
            (ref_phases if core.compiled("phase") is None else comp_phases)[i // 4]._xi_at(t)

    out = {}
    for label, fn, n in (("setup", setups, len(phases)), ("energy", energy_calls, len(energies)),
                         ("xi_at", states, len(times))):
        with core.reference():
            ref = best(fn, repeat)
        comp = best(fn, repeat)
        out[label] = {"calls": n, "python_us": 1e6 * ref / n, "compiled_us": 1e6 * comp / n, "speedup": ref / comp}
    out["events"] = len(res.events)
    return out


def end_to_end(scene, repeat: int) -> dict:
    n = len(run_scene(scene, "exact")[0].events)
    with core.reference():
        ref = best(lambda: run_scene(scene, "exact"), repeat)
    comp = best(lambda: run_scene(scene, "exact"), repeat)
    per = max(n, 1)
    return {"events": n, "python_s": ref, "compiled_s": comp, "python_ms_per_event": 1e3 * ref / per,
            "compiled_ms_per_event": 1e3 * comp / per, "speedup": ref / comp}


def profile(scene, top: int = 25) -> list[dict]:
    """The compiled run's functions by own time (ms per event)."""
    n = max(len(run_scene(scene, "exact")[0].events), 1)
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    run_scene(scene, "exact")
    prof.disable()
    stats = pstats.Stats(prof).stats
    rows = sorted(((v[2], v[3], v[1], k) for k, v in stats.items()), reverse=True)[:top]
    return [{"function": f"{Path(k[0]).name}:{k[1]}({k[2]})", "calls": calls, "tottime_ms_per_event": 1e3 * tt / n,
             "cumtime_ms_per_event": 1e3 * ct / n} for tt, ct, calls, k in rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="best of 3, the shipped scene over 0.3 s")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=None, help="runs per timing (best of them)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "core_phase"))
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 5)
    if core.compiled("phase") is None:
        raise SystemExit(f"core_phase: the compiled part 'phase' is not active ({core.name()})")
    stop = load_scene("default", STOP)
    shipped = load_scene("default", [f"simulation.t_end={0.3 if args.quick else 1.0}"])
    payload = {"machine": machine(), "core": core.name(), "repeat": repeat,
               "kernels_stop": kernels(stop, repeat),
               "stop": end_to_end(stop, repeat), "shipped": end_to_end(shipped, repeat),
               "profile_stop_compiled": profile(stop)}
    rows = [{"case": f"kernel {k}", **v} for k, v in payload["kernels_stop"].items() if isinstance(v, dict)]
    rows += [{"case": name, **payload[name]} for name in ("stop", "shipped")]
    write_outputs(Path(args.out), "core_phase", rows, payload)
    if args.json:
        print(json.dumps(payload))
        return
    for r in rows:
        print(r)
    for p in payload["profile_stop_compiled"]:
        print(f"{p['tottime_ms_per_event']:8.4f} {p['cumtime_ms_per_event']:8.4f} {p['calls']:7d} {p['function']}")


if __name__ == "__main__":
    main()
