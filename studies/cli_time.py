"""``nsfem run`` on the shipped scene as a whole command, this tree against the commit issue 33 starts from.

Issue 33's goal: the command does not get slower (the compiled core must not cost more at import than it
saves). Each round runs ``python -m nsfem run --json --out DIR`` (the shipped scene as shipped: model, run,
VTU/PVD and PNG outputs) once on the baseline's sources (``git archive BASE`` into a temporary folder, its
pure-Python code) and once on this tree (its compiled core where built), each in a fresh interpreter with
``PYTHONPATH`` on its tree; ``--repeat`` rounds, the fastest whole-command wall time of each kept, with the
integration's own wall time beside it.

    python studies/cli_time.py [--quick] [--json] [--base 1b69cae] [--repeat 3]

``--quick``: 3 rounds (5 without). Writes cli_time.json/.csv into studies/out/cli_time.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from study_io import machine, write_outputs

ROOT = Path(__file__).resolve().parents[1]


def one(tree: str, out: str) -> dict:
    """One whole ``nsfem run`` of the shipped scene on ``tree``: wall time, and the run's own figures."""
    env = {**os.environ, "PYTHONPATH": tree, "MPLBACKEND": "Agg"}
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "nsfem", "run", "--json", "--out", out], env=env, cwd=tree,
                         capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if run.returncode:
        return {"error": (run.stderr.strip().splitlines() or ["?"])[-1], "command_s": wall}
    found = json.loads(run.stdout)
    # (``integration_wall_s`` the integration alone; ``wall_s`` the run with its outputs; a commit before
    # the former has the latter only)
    return {"command_s": wall, "integration_s": found.get("integration_wall_s", found.get("wall_s")),
            "run_s": found.get("wall_s"), "events": found.get("events"),
            "core": found.get("core", "python (before issue 33)")}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 rounds")
    ap.add_argument("--json", action="store_true", help="print one JSON object (progress to stderr)")
    ap.add_argument("--base", default="1b69cae", help="the commit to compare with (default: issue 33's start)")
    ap.add_argument("--repeat", type=int, default=None, help="rounds (5; --quick 3)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "cli_time"))
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr if args.json else sys.stdout, flush=True)
    repeat = args.repeat or (3 if args.quick else 5)
    best: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        base.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.base], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive.stdout, check=True)
        for _ in range(repeat):
            for label, tree in (("base", str(base)), ("this", str(ROOT))):
                r = one(tree, str(Path(tmp) / f"out_{label}"))
                say(f"{label}: " + (f"{r['command_s']:.2f} s whole, {r['integration_s']:.3f} s integrating, "
                                    f"core {r['core']}" if "error" not in r else f"failed: {r['error']}"))
                if "error" not in r and r["command_s"] < best.get(label, {}).get("command_s", float("inf")):
                    best[label] = r
    ratio = best["base"]["command_s"] / best["this"]["command_s"] if {"base", "this"} <= best.keys() else None
    payload = {"base_commit": args.base, "repeat": repeat, **best, "base_over_this": ratio,
               "not_slower": ratio is not None and ratio >= 1.0, "machine": machine()}
    write_outputs(Path(args.out), "cli_time", [{"tree": k, **v} for k, v in best.items()], payload)
    if ratio is not None:
        say(f"nsfem run, shipped scene, whole command (best of {repeat}): {args.base} {best['base']['command_s']:.2f} s, "
            f"this tree {best['this']['command_s']:.2f} s ({ratio:.2f}x; goal: not slower -- "
            + ("met)" if ratio >= 1.0 else "NOT met)"))
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
