"""The exact method's run time, side by side: a baseline commit, this tree's pure-Python event core and its
compiled core, measured in one run (issue 33).

Each version runs in its own interpreter (``PYTHONPATH`` set to its source tree: the baseline is checked out
into a temporary ``git worktree``; this tree needs its compiled core built in place, ``python setup.py
build_ext --inplace``, or installed), one after the other per case and repetition, so the machine's load
falls on all of them alike; the best of ``--repeat`` runs is kept. Reported per case and version: the
integration's wall time (``Result.wall_s``: what the event core changes; the model's assembly and reduction
are the same in all), events, ms per event, energy residual; and the ratios baseline / compiled and
pure Python / compiled. The event sequences of the versions are compared (count, kinds; largest relative
difference of the event times).

    python studies/side_by_side.py [--baseline REV] [--repeat N] [--quick] [--json] [--cases a,b,...]

Writes side_by_side.json/.csv into studies/out/side_by_side.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from study_io import machine, write_outputs

ROOT = Path(__file__).resolve().parents[1]
STOP = 'obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]'

#: name: (scene, overrides, quick overrides)
CASES = {
    "shipped": ("default", ["simulation.t_end=1.0"], ["simulation.t_end=1.0"]),
    "stop": ("default", [STOP, "simulation.t_end=0.05"], [STOP, "simulation.t_end=0.05"]),
    "friction": ("default", ["delamination.0.friction=0.3", "simulation.t_end=1.0"],
                 ["delamination.0.friction=0.3", "simulation.t_end=0.3"]),
    "crack": ("crack", [], ["simulation.t_end=0.2"]),
    "rub": ("rub", [], ["simulation.t_end=0.3"]),
    "retainer_drop": ("retainer_drop", [], ["simulation.t_end=0.05"]),
}

CHILD = r'''
import json, sys
from nsfem import load_scene
from nsfem.simulate import run_scene
try:
    from nsfem.integrate import core
    name = core.name()
except ImportError:
    name = "pure Python (before the compiled core)"
scene, overrides = sys.argv[1], json.loads(sys.argv[2])
res, _ = run_scene(load_scene(scene, overrides), "exact")
print(json.dumps({"wall_s": res.wall_s, "events": len(res.events), "impacts": len(res.impacts),
                  "times": [e["t"] for e in res.events], "kinds": [e["kinds"] for e in res.events],
                  "energy_residual": res.energy.get("relative_residual"), "core": name}))
'''


def versions(baseline: str | None, tmp: Path) -> list[tuple[str, Path, dict]]:
    """(label, source tree, extra environment) of each version to run."""
    out = []
    if baseline:
        tree = tmp / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree), baseline], check=True)
        out.append((f"baseline {baseline}", tree, {"NSFEM_PURE_PYTHON": "1"}))
    out.append(("pure Python", ROOT, {"NSFEM_PURE_PYTHON": "1"}))
    out.append(("compiled", ROOT, {"NSFEM_PURE_PYTHON": "0"}))
    return out


def run_one(tree: Path, extra: dict, scene: str, overrides: list) -> dict:
    env = {**os.environ, **extra, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, "-c", CHILD, scene, json.dumps(overrides)], env=env, cwd=tree,
                          capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        raise SystemExit(f"side_by_side: {scene} {overrides} failed in {tree}:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def compare(a: dict, b: dict) -> dict:
    """Whether two runs have the same event sequence, and their largest relative event-time difference."""
    same = a["events"] == b["events"] and a["kinds"] == b["kinds"]
    dt = max((abs(x - y) / max(1.0, abs(x)) for x, y in zip(a["times"], b["times"])), default=0.0)
    return {"same_sequence": same, "max_time_diff_rel": dt}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", default=None, help="a git revision to run beside this tree (e.g. 1b69cae)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="shorter runs of the long scenes")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--out", default=str(ROOT / "studies" / "out" / "side_by_side"))
    args = ap.parse_args(argv)
    names = [c for c in args.cases.split(",") if c]
    unknown = [c for c in names if c not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; known: {', '.join(CASES)}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        vers = versions(args.baseline, Path(tmp))
        try:
            for case in names:
                scene, full, quick = CASES[case]
                overrides = quick if args.quick else full
                best: dict = {}
                for _ in range(args.repeat):
                    for label, tree, extra in vers:
                        r = run_one(tree, extra, scene, overrides)
                        if label not in best or r["wall_s"] < best[label]["wall_s"]:
                            best[label] = r
                comp = best["compiled"]
                for label, _, _ in vers:
                    r = best[label]
                    row = {"case": case, "version": label, "core": r["core"], "wall_s": r["wall_s"],
                           "events": r["events"], "impacts": r["impacts"],
                           "ms_per_event": 1e3 * r["wall_s"] / max(r["events"], 1),
                           "energy_residual": r["energy_residual"], "over_compiled": r["wall_s"] / comp["wall_s"],
                           **compare(r, comp)}
                    rows.append(row)
                    if not args.json:
                        print("  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()),
                              flush=True)
        finally:
            if args.baseline:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(Path(tmp) / "baseline")],
                               check=False)
    payload = {"machine": machine(), "baseline": args.baseline, "repeat": args.repeat, "quick": args.quick, "rows": rows}
    write_outputs(Path(args.out), "side_by_side", rows, payload)
    if args.json:
        print(json.dumps(payload, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
