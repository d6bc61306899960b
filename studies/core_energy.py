"""The closed-form energy of phases with divided-difference groups (issue 33, retainer_drop) against the
quadrature it replaced and the compiled kernel against its Python reference.

Side by side in one process, best of ``--repeat`` runs in CPU time of the process (the machine is shared),
OPENBLAS_NUM_THREADS=1:

- per energy call, on every call of a retainer_drop run (each of its phases has rigid-body groups: a free rotor
  on its retainer rings), replayed on the captured inputs: the closed form on the compiled core, on the
  pure-Python core (``core.reference()``), and the Gauss-Legendre quadrature the exact method used before
  (its branch of ``EventDriven._energy``), with each path's largest difference from the compiled closed form
  per term (relative to the call's turnover);
- the kernel alone: ``group_integrals`` compiled and Python on the same calls' groups;
- end to end, ms per event both ways: retainer_drop (0.2 s, ``--quick`` 0.05 s), the stop scene (the shipped shaft
  with a stop 0.2 mm under midspan, 0.05 s: 282 events) and the shipped scene over 1 s (no groups there: they
  show that nothing else moved);
- where the compiled retainer_drop run's time per event goes: cProfile (CPU time), by function (tottime).

    OPENBLAS_NUM_THREADS=1 python studies/core_energy.py [--quick] [--json] [--out DIR]

Writes core_energy.json/.csv into studies/out/core_energy.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from core_phase import STOP, best, end_to_end, profile
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import closed_form, core
from nsfem.integrate import event_driven as ed_mod
from nsfem.simulate import run_scene


def capture(scene) -> list:
    """The arguments of every energy call of a run, and the integrator's system at the call."""
    calls = []
    energy = ed_mod.EventDriven._energy

    def rec(self, phase, mode, xi_fun, t0, t1, K, P, D, totals, ends=None):
        calls.append((self, phase, mode, xi_fun, t0, t1, K, P, D, dict(totals), ends, self.system))
        return energy(self, phase, mode, xi_fun, t0, t1, K, P, D, totals, ends)

    ed_mod.EventDriven._energy = rec
    try:
        run_scene(scene, "exact")
    finally:
        ed_mod.EventDriven._energy = energy
    return calls


def _call(e, quadrature: bool = False) -> dict:
    """One captured energy call; its increments per term. ``quadrature``: the exact method's quadrature branch."""
    self, totals = e[0], dict(e[9])
    self.system = e[11]           # the system of the call (a round ring's turns)
    if quadrature:
        self._energy_closed_form = self._energy_without_quadrature = lambda *a, **k: None
    try:
        self._energy(*e[1:9], totals, e[10])
    finally:
        if quadrature:
            del self._energy_closed_form, self._energy_without_quadrature
    return {k: totals[k] - e[9][k] for k in totals}


def energy_calls(scene, repeat: int) -> dict:
    calls = capture(scene)
    with_groups = sum(1 for e in calls if e[1]._modal is not None and e[1]._modal.groups)
    ref = [_call(e) for e in calls]
    out = {"calls": len(calls), "calls_with_groups": with_groups}
    for label, quad, reference in (("compiled", False, False), ("python", False, True), ("quadrature", True, False)):
        def run(quad=quad):
            for e in calls:
                _call(e, quad)
        if reference:
            with core.reference():
                t = best(run, repeat)
                got = [_call(e) for e in calls]
        else:
            t = best(run, repeat)
            got = [_call(e, quad) for e in calls]
        diff = max(max(abs(g[k] - r[k]) for k in r) / max(sum(abs(v) for v in r.values()), 1e-300)
                   for g, r in zip(got, ref))
        out[label] = {"us_per_call": 1e6 * t / len(calls), "max_difference_of_turnover": diff}
    # the kernel alone, on the groups of the same calls
    args = []
    for e in calls:
        terms = e[1].closed_form_terms()
        if terms is not None and terms[2]:
            args.append((terms[1], terms[2], e[5] - e[1].t0))
    kernel = core.compiled("phase")

    def python():
        for nu, groups, T in args:
            closed_form.group_integrals(nu, groups, T)

    def compiled():
        for nu, groups, T in args:
            ed_mod._compiled_group_integrals(kernel, nu, groups, T, True)

    tp, tc = best(python, repeat), best(compiled, repeat)
    worst = 0.0
    for nu, groups, T in args:
        Pe, Pg = closed_form.group_integrals(nu, groups, T)
        Qe, Qg = ed_mod._compiled_group_integrals(kernel, nu, groups, T, True)
        worst = max(worst, float(np.abs(Qe - Pe).max(initial=0.0) / max(np.abs(Pe).max(initial=0.0), 1e-300)),
                    float(np.abs(Qg - Pg).max(initial=0.0) / max(np.abs(Pg).max(initial=0.0), 1e-300)))
    out["group_integrals"] = {"calls": len(args), "python_us": 1e6 * tp / max(len(args), 1),
                              "compiled_us": 1e6 * tc / max(len(args), 1), "speedup": tp / tc,
                              "max_difference_of_block": worst}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="best of 3, retainer_drop over 0.05 s, the shipped scene 0.3 s")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=None, help="runs per timing (best of them)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "core_energy"))
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 5)
    if core.compiled("phase") is None:
        raise SystemExit(f"core_energy: the compiled part 'phase' is not active ({core.name()})")
    drop = load_scene("retainer_drop", [f"simulation.t_end={0.05 if args.quick else 0.2}"])
    payload = {"machine": machine(), "core": core.name(), "repeat": repeat,
               "energy_retainer_drop": energy_calls(drop, repeat),
               "retainer_drop": end_to_end(drop, repeat),
               "stop": end_to_end(load_scene("default", STOP), repeat),
               "shipped": end_to_end(load_scene("default", [f"simulation.t_end={0.3 if args.quick else 1.0}"]), repeat),
               "profile_retainer_drop_compiled": profile(drop)}
    rows = [{"case": f"energy {k}", **v} for k, v in payload["energy_retainer_drop"].items() if isinstance(v, dict)]
    rows += [{"case": name, **payload[name]} for name in ("retainer_drop", "stop", "shipped")]
    write_outputs(Path(args.out), "core_energy", rows, payload)
    if args.json:
        print(json.dumps(payload))
        return
    for r in rows:
        print(r)
    for p in payload["profile_retainer_drop_compiled"]:
        print(f"{p['tottime_ms_per_event']:8.4f} {p['cumtime_ms_per_event']:8.4f} {p['calls']:7d} {p['function']}")


if __name__ == "__main__":
    main()
