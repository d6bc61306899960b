"""Elastic rings on the exact method's compiled core: where an event's time goes on ROSS's rub (issue 33).

ROSS's rub example (studies/ross_rub.toml: Craig-Bampton 12, an elastic ring of 64 or 16 facets) makes a
configuration at most events as the shaft slides round the ring. This study runs it, with the stop scene and the
shipped scene 1 s for comparison (no rings), on both cores in one process (the compiled one and the reference by
``core.reference()``, alternating, best of ``--repeat``: the least disturbed run on a shared machine; the
run's CPU time is printed beside its wall time), and breaks each run's integration time into parts,
timed around the integrator's own functions: search (``first_event``), LCPs (``resolve``), configurations
(``EventDriven.configuration``: their construction and eigen-decompositions), phase set-up (``_phase`` without
its configuration, ``event_rows``), energy (``_energy``), the rest (the loop, ring bookkeeping, outputs).
``--base CHECKOUT`` runs the same in a child process on another checkout (its own PYTHONPATH) for the before
and after; ``--profile`` prints the compiled run's functions by their own time per event.

    OPENBLAS_NUM_THREADS=1 python studies/elastic_rings.py [--base /path/to/checkout] [--repeat 3] [--quick] [--json] [--profile]

Writes elastic_rings.json/.csv into studies/out/elastic_rings.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "out" / "elastic_rings"

CHILD = r'''
import cProfile, io, json, pstats, sys, time
from pathlib import Path
import nsfem
from nsfem import load_scene
from nsfem.integrate import core
from nsfem.integrate import event_driven as ed
from nsfem.simulate import run_scene

here, repeat, quick, profile = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "1", sys.argv[4] == "1"
ross = str(here / "ross_rub.toml")
t_ross = "0.25" if quick else "0.5"
CASES = {
    "ross_rub_64": (ross, [f"simulation.t_end={t_ross}"]),
    "ross_rub_16": (ross, [f"simulation.t_end={t_ross}", "stator.0.facets=16"]),
    "stop": ("default", ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]', "simulation.t_end=0.05"]),
    "shipped_1s": ("default", ["simulation.t_end=1.0"]),
}
parts = dict.fromkeys(("search", "lcp", "configurations", "phase", "energy"), 0.0)

def timed(owner, name, part, method=False, minus=None):
    f = getattr(owner, name)
    def wrap(*a, **k):
        before = parts[minus] if minus else 0.0
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            parts[part] += time.perf_counter() - t - ((parts[minus] - before) if minus else 0.0)
    setattr(owner, name, wrap)

timed(ed, "first_event", "search")
timed(ed, "resolve", "lcp")
timed(ed, "event_rows", "phase")
timed(ed.EventDriven, "configuration", "configurations")
timed(ed.EventDriven, "_phase", "phase", minus="configurations")
timed(ed.EventDriven, "_energy", "energy")

def once(scene, reference):
    for k in parts:
        parts[k] = 0.0
    t0, c0 = time.perf_counter(), time.process_time()
    if reference:
        with core.reference():
            res, _ = run_scene(scene, "exact")
    else:
        res, _ = run_scene(scene, "exact")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"run_scene_s": wall, "run_scene_cpu_s": cpu, "integration_s": res.wall_s, "events": len(res.events),
            "configurations": res.info.get("configurations"), "decompositions": res.info.get("decompositions"),
            "parts": dict(parts), "times": [e["t"] for e in res.events], "kinds": [e["kinds"] for e in res.events]}

out = {"nsfem": nsfem.__file__, "core": core.name(), "cases": {}}
for case, (name, ov) in CASES.items():
    scene = load_scene(name, ov)
    run_scene(scene, "exact")          # warm: imports, caches of the model's assembly
    best = {}
    for _ in range(repeat):
        for label, ref in (("compiled", False), ("python", True)):
            r = once(scene, ref)
            if label not in best or r["integration_s"] < best[label]["integration_s"]:
                best[label] = r
    if profile and case.startswith("ross_rub_64"):
        pr = cProfile.Profile()
        pr.enable()
        res, _ = run_scene(scene, "exact")
        pr.disable()
        s = io.StringIO()
        st = pstats.Stats(pr, stream=s)
        st.sort_stats("tottime").print_stats(25)
        best["profile"] = s.getvalue()
    out["cases"][case] = best
print(json.dumps(out))
'''


def run(root: Path, repeat: int, quick: bool, profile: bool) -> dict:
    root = Path(root).resolve()
    env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg", OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", CHILD, str(HERE), str(repeat), "1" if quick else "0",
                           "1" if profile else "0"], env=env, capture_output=True, text=True, cwd=root)
    if done.returncode != 0:
        raise SystemExit(f"elastic_rings: the run on {root} failed:\n{done.stderr[-3000:]}")
    found = json.loads(done.stdout.strip().splitlines()[-1])
    if not Path(found["nsfem"]).resolve().is_relative_to(root):
        raise SystemExit(f"elastic_rings: the child of {root} imported {found['nsfem']}")
    return found


def _line(label: str, r: dict) -> str:
    n = max(r["events"], 1)
    per = ", ".join(f"{k} {1e3 * v / n:.3f}" for k, v in r["parts"].items())
    rest = r["integration_s"] - sum(r["parts"].values())
    return (f"    {label:18s} run_scene {r['run_scene_s']:.3f} s (cpu {r['run_scene_cpu_s']:.3f}), integration {r['integration_s']:.3f} s, {r['events']} events, "
            f"{r['configurations']} configurations ({r['decompositions']} decomposed); ms/event "
            f"{1e3 * r['integration_s'] / n:.3f} ({per}, rest {1e3 * rest / n:.3f})")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", type=Path, help="another checkout to run side by side (its root folder)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="ROSS's rub over 0.25 s instead of 0.5 s")
    ap.add_argument("--profile", action="store_true", help="print the compiled run's functions by own time")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    roots = {"this": HERE.parent, **({"base": args.base} if args.base else {})}
    versions: dict = {}
    for i in range(args.repeat):       # the checkouts alternate (the machine is shared): best of each
        for vname, root in roots.items():
            found = run(root, 1, args.quick, args.profile and vname == "this" and i == 0)
            best = versions.setdefault(vname, found)
            for case, runs in found["cases"].items():
                for core in ("compiled", "python"):
                    if runs[core]["integration_s"] < best["cases"][case][core]["integration_s"]:
                        best["cases"][case][core] = runs[core]
    rows = []
    for case in versions["this"]["cases"]:
        print(case, file=sys.stderr)
        this = versions["this"]["cases"][case]
        for vname, found in versions.items():
            for core in ("compiled", "python"):
                r = found["cases"][case][core]
                print(_line(f"{vname} {core}", r), file=sys.stderr)
                rows.append({"case": case, "version": vname, "core": core, **{k: v for k, v in r.items()
                                                                               if k not in ("parts", "times", "kinds")},
                             "ms_per_event": 1e3 * r["integration_s"] / max(r["events"], 1),
                             **{f"{k}_s": v for k, v in r["parts"].items()}})
        c, p = this["compiled"], this["python"]
        same = c["kinds"] == p["kinds"]
        dt = max((abs(a - b) / max(1.0, abs(a)) for a, b in zip(c["times"], p["times"])), default=0.0)
        print(f"    compiled vs python: x{p['integration_s'] / c['integration_s']:.2f}; same event kinds {same}, "
              f"times within {dt:.1e}", file=sys.stderr)
        if "base" in versions:
            b = versions["base"]["cases"][case]["compiled"]
            same_b = b["kinds"] == c["kinds"]
            dt_b = max((abs(x - y) / max(1.0, abs(x)) for x, y in zip(b["times"], c["times"])), default=0.0)
            print(f"    this vs base (compiled): x{b['integration_s'] / c['integration_s']:.2f} integration, "
                  f"x{b['run_scene_s'] / c['run_scene_s']:.2f} run_scene; same event kinds {same_b}, times within "
                  f"{dt_b:.1e}", file=sys.stderr)
        if "profile" in this:
            print(this["profile"], file=sys.stderr)
    sys.path.insert(0, str(HERE))
    from study_io import machine, write_outputs

    payload = {"machine": machine(), "quick": args.quick, "repeat": args.repeat, "base": str(args.base) if args.base else None,
               "rows": rows}
    write_outputs(args.out, "elastic_rings", rows, payload)
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
