"""Where the exact method's time goes, per event, on both event cores side by side (issue 33's goals).

Per case, in this one process, the compiled core and the pure-Python reference (``core.reference()``)
alternating, best of ``--repeat`` runs each: the integration's wall time, its events, ms per event,
and the split of the wall time into the parts of the per-event path (each part at its fastest over the
runs), each timed exclusively (a part's time excludes the parts it calls, e.g. a phase's set-up excludes
the configuration it builds):

- ``search``: the event search (``first_event`` through the integrator's ``_advance``);
- ``lcp``: the impact and transition LCPs and their bookkeeping (``resolve``, ``hold_degenerate``);
- ``phase``: a phase's set-up (``_phase``, ``event_rows``, ``check_phase``);
- ``configurations``: the configurations met (``EventDriven.configuration``: a cache look-up or a new
  eigen-decomposition);
- ``energy``: the work integrals (``_energy``);
- ``outputs``: the outputs (``_outputs``, ``Memory.observe``);
- ``loop``: the rest (the event loop's own Python, the states at the phase ends, the guard).

Then a cProfile of the compiled run: the functions with the largest own time (``--top``).

Cases: ``stop`` (the shipped shaft with a stop 0.2 mm under midspan, restitution 0.5, 0.05 s: 282 events),
``shipped`` (1 s), ``unreduced`` (the shipped scene with ``reduction.method = "none"``, 3 s from rest;
``--quick``: 1 s), ``rub`` (the shipped rub, 1 s), ``fig3-modal16`` and ``fig3-cb16`` (figure 3's runs of
studies/paper_figure3.py at its first gravity resonance from the open orbit, 0.1 s).

    python studies/profile_exact.py [--quick] [--json] [--cases stop,shipped,...] [--repeat 3] [--top 15] [--update]

``--update`` keeps the saved JSON's other cases (rerun one case in a quieter moment, say).

Writes profile_exact.json/.csv into studies/out/profile_exact.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import functools
import io
import json
import pstats
import sys
import time
from pathlib import Path

from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import core, integrate
from nsfem.integrate import event_driven as ed
from nsfem.integrate import transitions
from nsfem.fem.assemble import build_model
from nsfem.integrate import ContactSystem
from nsfem.reduce import scene_reduction
from nsfem.simulate import initial_state, integrator_options

PARTS = ("search", "lcp", "phase", "configurations", "energy", "outputs")
CASES = ("stop", "shipped", "unreduced", "rub", "fig3-modal16", "fig3-cb16")
STOP = ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]', "simulation.t_end=0.05"]


class Split:
    """Exclusive wall time per part: the innermost timed function running owns the time."""

    def __init__(self):
        self.spent = dict.fromkeys(PARTS, 0.0)
        self.stack: list[list] = []   # [part, start of its current slice]
        self.patched: list[tuple] = []

    def wrap(self, owner, name: str, part: str) -> None:
        f = getattr(owner, name)

        @functools.wraps(f)
        def timed(*a, **k):
            now = time.perf_counter()
            if self.stack:   # pause the enclosing part
                outer = self.stack[-1]
                self.spent[outer[0]] += now - outer[1]
            self.stack.append([part, now])
            try:
                return f(*a, **k)
            finally:
                end = time.perf_counter()
                p, start = self.stack.pop()
                self.spent[p] += end - start
                if self.stack:
                    self.stack[-1][1] = end

        self.patched.append((owner, name, f))
        setattr(owner, name, timed)

    def __enter__(self):
        self.wrap(ed, "first_event", "search")
        self.wrap(ed.Exact, "_advance", "search")
        self.wrap(ed, "resolve", "lcp")
        self.wrap(ed, "hold_degenerate", "lcp")
        self.wrap(ed.EventDriven, "_phase", "phase")
        self.wrap(ed, "event_rows", "phase")
        self.wrap(ed, "check_phase", "phase")
        self.wrap(ed.EventDriven, "configuration", "configurations")
        self.wrap(ed.EventDriven, "_energy", "energy")
        self.wrap(ed.EventDriven, "_outputs", "outputs")
        self.wrap(transitions.Memory, "observe", "outputs")
        return self

    def __exit__(self, *exc):
        for owner, name, f in reversed(self.patched):
            setattr(owner, name, f)


def runner(case: str, quick: bool):
    """A callable that integrates ``case`` once with ``exact`` and returns its Result."""
    if case.startswith("fig3"):
        sys.path.insert(0, str(Path(__file__).parent))
        import paper_figure3 as p3

        red = "modal" if case == "fig3-modal16" else "craig-bampton"
        model = p3.Model(p3.REDUCTIONS[red])
        rep = p3.campbell_report(model.scene, model.fe, [0.0], 6, model.red)
        speed = rep["gravity_resonances_hz"]["open"][0]
        ce = 1e-3 / p3.zeta_of(model, 1.0)
        S, q0, v0, _ = p3.start_on_orbit(None, model, speed, ce)
        return lambda: integrate(S, 0.1, "exact", 5e-4, q0, v0)
    name, ov = {"stop": (None, STOP), "shipped": (None, ["simulation.t_end=1.0"]),
                "unreduced": (None, ['reduction.method="none"', f"simulation.t_end={1.0 if quick else 3.0}"]),
                "rub": ("rub", ["simulation.t_end=1.0"])}[case]
    scene = load_scene(name, ov)
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    q0, v0 = initial_state(scene, model, red, system)
    sim = scene.simulation
    # what run_scene integrates, without its set-up (built once here)
    return lambda: integrate(system, sim.t_end, "exact", sim.output_dt, q0, v0, **integrator_options(sim, "exact"))


def measure(run, repeat: int, labels: tuple[str, ...]) -> dict:
    """Per core of ``labels`` ("compiled", "python"), the runs alternating between them, ``repeat`` each: the
    integration's fastest wall time, and each part at its own fastest over the runs (the machine is shared:
    a busy spell in one part of the fastest run would show in its split; ``loop`` too: the parts' minima
    sum to at most the fastest run)."""
    best: dict = {}
    parts: dict = {}
    for _ in range(repeat):
        for label in labels:
            with Split() as sp, (core.reference() if label == "python" else contextlib.nullcontext()):
                res = run()
            spent = {**sp.spent, "loop": res.wall_s - sum(sp.spent.values())}
            parts[label] = spent if label not in parts else {k: min(v, spent[k]) for k, v in parts[label].items()}
            if label not in best or res.wall_s < best[label]["wall_s"]:
                best[label] = {"wall_s": res.wall_s, "events": len(res.events),
                               "configurations": res.info.get("configurations"), "repeat": repeat}
    for label, b in best.items():
        n = max(b["events"], 1)
        b["ms_per_event"] = 1e3 * b["wall_s"] / n
        b["parts_ms_per_event"] = {k: 1e3 * v / n for k, v in parts[label].items()}
    return best


def profile(run, top: int) -> list[dict]:
    """The ``top`` functions by own time in one run under cProfile."""
    pr = cProfile.Profile()
    pr.enable()
    run()
    pr.disable()
    st = pstats.Stats(pr, stream=io.StringIO())
    rows = []
    for (file, line, name), (cc, nc, tt, ct, _) in st.stats.items():
        rows.append({"function": f"{Path(file).name}:{line}({name})", "calls": nc, "own_s": tt, "cumulative_s": ct})
    return sorted(rows, key=lambda r: -r["own_s"])[:top]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="best of 1, the unreduced run 1 s")
    ap.add_argument("--json", action="store_true", help="print one JSON object (tables to stderr)")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--repeat", type=int, default=None, help="runs per core, the best kept (3; --quick 1)")
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("--update", action="store_true", help="keep the other cases of the saved JSON (rerun some)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "profile_exact"))
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr if args.json else sys.stdout, flush=True)
    repeat = args.repeat or (1 if args.quick else 3)
    saved = Path(args.out) / "profile_exact.json"
    found = json.loads(saved.read_text()) if args.update and saved.is_file() else {}
    found.update({"core": core.name(), "machine": machine()})
    for case in args.cases.split(","):
        run = runner(case, args.quick)
        entry = measure(run, repeat, ("compiled", "python") if core.name() == "compiled" else ("python",))
        if "compiled" in entry:
            entry["python_over_compiled_per_event"] = entry["python"]["ms_per_event"] / entry["compiled"]["ms_per_event"]
            entry["profile_compiled"] = profile(run, args.top)
        found[case] = entry
        say(f"{case}: " + "; ".join(f"{k} {e['wall_s']:.3f} s, {e['events']} events, {e['ms_per_event']:.3f} ms/event"
                                    for k, e in entry.items() if k in ("compiled", "python"))
            + (f"; python / compiled per event {entry['python_over_compiled_per_event']:.2f}x"
               if "compiled" in entry else ""))
        for k in ("compiled", "python"):
            if k in entry:
                say(f"    {k:8s} ms/event: " + ", ".join(f"{p} {v:.3f}" for p, v in
                                                          entry[k]["parts_ms_per_event"].items()))
        for r in entry.get("profile_compiled", [])[:args.top]:
            say(f"      {r['own_s']:8.3f} s own {r['cumulative_s']:8.3f} s cum {r['calls']:8d} calls  {r['function']}")
    rows = [{"case": case, "core": label, **{k: v for k, v in e[label].items() if k != "parts_ms_per_event"},
             **{f"{k}_ms_per_event": v for k, v in e[label]["parts_ms_per_event"].items()}}
            for case, e in found.items() if case in CASES for label in ("compiled", "python") if label in e]
    write_outputs(Path(args.out), "profile_exact", rows, found)
    if args.json:
        print(json.dumps(found))
    return found


if __name__ == "__main__":
    main()
