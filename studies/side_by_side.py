"""The exact method's cost, side by side with another checkout of nsfem (issue 33, "cheap first").

Each case runs in a child process per checkout (its own PYTHONPATH, so each imports its own code),
alternating the two, best of ``--repeat`` runs (the machine is shared: the best run is the one least
disturbed). Per run: the wall time of the integration (``Result.wall_s``), the process's CPU time over
the same span, the events, and a breakdown of the integration's wall time by part, timed in the run
around the integrator's own functions (search: ``first_event``; LCPs: ``resolve``; phase set-up:
``_phase`` and ``event_rows``; energy: ``_energy``; the rest: outputs, checks, the loop itself).

Cases: the shipped scene 1 s; the stop scene of studies/work_precision.py (a stop 0.2 mm under
midspan, restitution 0.5) 0.05 s; the rub of tests/test_stator.py (16 facets, Craig-Bampton 4) with
Rayleigh beta 1e-4 (its stiff modes overdamped) and 1e-5, 4 s; the shipped rub (2 s, with beta 1e-5 on
both checkouts: the scene ships it since issue 33), retainer_drop (0.2 s; since issue 33 it asks for round
rings, which a checkout before it reads as the polygon) and crack (1 s). The base always runs its
pure-Python core; ``--cores`` runs this checkout on both cores (``this-python``, ``this``).

    python studies/side_by_side.py --base /path/to/other/checkout [--cores] [--repeat 3] [--quick] [--json] [--cases stop,...]

Prints a table (and with ``--json`` one object {case: {"base": {...}, "this": {...}}}); writes
side_by_side.json/.csv into studies/out/side_by_side.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "out" / "side_by_side"
CASES = ("shipped", "stop", "rub_beta_1e-4", "rub_beta_1e-5", "rub", "retainer_drop", "crack")

CHILD = r'''
import json, math, sys, time
case = sys.argv[1]
import nsfem
from nsfem.integrate import event_driven as ed
parts = {"search": 0.0, "lcp": 0.0, "phase": 0.0, "energy": 0.0}

def timed(owner, name, part, method=False):
    f = getattr(owner, name)
    if method:
        def wrap(self, *a, **k):
            t = time.perf_counter()
            try:
                return f(self, *a, **k)
            finally:
                parts[part] += time.perf_counter() - t
    else:
        def wrap(*a, **k):
            t = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                parts[part] += time.perf_counter() - t
    setattr(owner, name, wrap)

timed(ed, "first_event", "search")
timed(ed, "resolve", "lcp")
timed(ed, "event_rows", "phase")
timed(ed.EventDriven, "_phase", "phase", True)
timed(ed.EventDriven, "_energy", "energy", True)
if case.startswith("rub_beta"):
    sys.path.insert(0, sys.argv[2])
    from test_stator import rub_tree
    from nsfem.scene import scene_from_tree
    scene = scene_from_tree(rub_tree(16, beta=float(case.split("_")[-1]), simulation={"t_end": 4.0, "output_dt": 1e-3}))
else:
    from nsfem import load_scene
    name, ov = {"shipped": (None, ["simulation.t_end=1.0"]),
                "stop": (None, ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]', "simulation.t_end=0.05"]),
                # the shipped rub as it now ships (beta 1e-5) on both checkouts: the same model
                "rub": ("rub", ["damping.rayleigh=[0.0,1e-5]"]),
                "retainer_drop": ("retainer_drop", []),
                "crack": ("crack", [])}[case]
    scene = load_scene(name, ov)
from nsfem.simulate import run_scene
for k in parts:
    parts[k] = 0.0
c0 = time.process_time()
res, _ = run_scene(scene, "exact")
cpu = time.process_time() - c0
print(json.dumps({"nsfem": nsfem.__file__, "wall_s": res.wall_s, "cpu_s": cpu, "events": len(res.events), "impacts": len(res.impacts),
                  "energy_residual": res.energy["relative_residual"], "parts": parts,
                  "times": [e["t"] for e in res.events], "kinds": [e["kinds"] for e in res.events]}))
'''


def run(root: Path, case: str, extra: dict | None = None) -> dict:
    root = Path(root).resolve()
    env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg", **(extra or {}))
    # (run from the checkout's root: ``python -c`` puts the working folder first on sys.path)
    out = subprocess.run([sys.executable, "-c", CHILD, case, str(root / "tests")], env=env, capture_output=True,
                         text=True, check=True, cwd=root)
    found = json.loads(out.stdout.strip().splitlines()[-1])
    if not Path(found["nsfem"]).resolve().is_relative_to(root):
        raise RuntimeError(f"{root}: the child imported {found['nsfem']}")
    return found


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", type=Path, required=True, help="the other checkout (its root folder)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one run each (about 30 s; the base's beta 1e-4 rub most)")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--cores", action="store_true", help="run this checkout on its pure-Python core too "
                    "(NSFEM_PURE_PYTHON=1, 'this-python') beside its compiled one")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    if args.quick:
        args.repeat = 1
    this = HERE.parent
    found: dict = {}
    rows = []
    for case in args.cases.split(","):
        best: dict = {}
        for _ in range(args.repeat):
            versions = [("base", args.base, {"NSFEM_PURE_PYTHON": "1"}), ("this", this, {})]
            if args.cores:
                versions.insert(1, ("this-python", this, {"NSFEM_PURE_PYTHON": "1"}))
            for name, root, extra in versions:
                r = run(root, case, extra)
                if name not in best or r["wall_s"] < best[name]["wall_s"]:
                    best[name] = r
        b, t = best["base"], best["this"]
        same = b["kinds"] == t["kinds"]
        dt = max((abs(x - y) / max(abs(x), 1e-300) for x, y in zip(b["times"], t["times"])), default=0.0)
        entry = {"base": {k: v for k, v in b.items() if k not in ("times", "kinds")},
                 "this": {k: v for k, v in t.items() if k not in ("times", "kinds")},
                 "same_event_kinds": same, "max_relative_time_difference": dt if same else None,
                 "ratio_wall": b["wall_s"] / t["wall_s"]}
        if "this-python" in best:
            p = best["this-python"]
            entry["this-python"] = {k: v for k, v in p.items() if k not in ("times", "kinds")}
            entry["python_over_compiled"] = p["wall_s"] / t["wall_s"]
            entry["python_over_compiled_per_event"] = (p["wall_s"] / max(p["events"], 1)) / (t["wall_s"] / max(t["events"], 1))
        found[case] = entry
        for name, r in best.items():
            rows.append({"case": case, "version": name, "wall_s": r["wall_s"], "cpu_s": r["cpu_s"],
                         "events": r["events"], "ms_per_event": 1e3 * r["wall_s"] / max(r["events"], 1),
                         **{f"{k}_s": v for k, v in r["parts"].items()}})
        print(f"{case:14s} base {b['wall_s']:.3f} s (cpu {b['cpu_s']:.3f}) this {t['wall_s']:.3f} s "
              f"(cpu {t['cpu_s']:.3f}) x{entry['ratio_wall']:.2f}; events {b['events']} / {t['events']}, "
              f"same kinds {same}, times within {dt:.1e}", file=sys.stderr, flush=True)
        for name, r in best.items():
            n = max(r["events"], 1)
            per = ", ".join(f"{k} {1e3 * v / n:.3f}" for k, v in r["parts"].items())
            print(f"    {name}: ms/event {1e3 * r['wall_s'] / n:.3f} ({per})", file=sys.stderr)
    sys.path.insert(0, str(HERE))
    from study_io import machine, write_outputs

    write_outputs(args.out, "side_by_side", rows, {"machine": machine(), "base": str(args.base), **found})
    if args.json:
        print(json.dumps(found))
    return found


if __name__ == "__main__":
    main()
