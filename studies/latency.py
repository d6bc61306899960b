"""How long a user waits: ``nsfem --help``, ``nsfem run --json`` without plots and VTU, and the whole
``nsfem run`` on the shipped scene, each as a fresh command (issue 34 point 10).

Goals (on the docs' machine, 2 cores shared): ``nsfem --help`` within 0.3 s, ``nsfem run --json`` with
``output.plots=[]`` and ``output.vtu_every=0`` within 0.8 s, the whole ``nsfem run`` (PNGs and VTU as
shipped) within 1.5 s. Each round runs the three commands once, each in a fresh interpreter
(``python -m nsfem ...``, ``PYTHONPATH`` on this tree), in a new output folder; one untimed round first
writes the bytecode cache (``PYTHONDONTWRITEBYTECODE`` is dropped for the children: an installed
package has its ``.pyc`` files, and compiling nsfem's sources costs 0.1-0.2 s per command) and warms the
file cache. Per command: the fastest and the median wall time of ``--repeat`` rounds and the median CPU
time (user + system of the child, less sensitive to other jobs on the machine than the wall time); a goal
is judged on the fastest wall time (other jobs only ever add to it). ``--breakdown`` adds one in-process
timing of the whole run's parts (imports, model and reduction, integration, results file, each plot,
VTU) and the heavy modules each command imported.

    python studies/latency.py [--quick] [--json] [--repeat 7] [--breakdown] [--base COMMIT] [--options]

``--base COMMIT``: the same commands on that commit's sources too (``git archive`` into a temporary folder, with
this tree's compiled core when the core's sources are the same, else its pure Python), interleaved with this
tree's round by round, so that both see the same load.

``--options``: also the whole run with one default changed (:data:`OPTIONS`: without phase.png, VTU every 20th
output time, without VTU, without plots), this tree only.

``--quick``: 3 rounds (7 without). Writes latency.json/.csv into studies/out/latency.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from study_io import machine, write_outputs

ROOT = Path(__file__).resolve().parents[1]
#: command name -> (arguments after ``python -m nsfem``, goal [s]); ``{out}`` is a fresh folder per run
COMMANDS = {
    "help": (["--help"], 0.3),
    "run_json_bare": (["run", "--json", "--out", "{out}", "--set", "output.plots=[]", "--set", "output.vtu_every=0"],
                      0.8),
    "run": (["run", "--out", "{out}"], 1.5),
}
#: with ``--options``: the whole run with one default changed, each a product decision this study does not take
#: (dropping a default plot or VTU frames), timed to say what each would give
OPTIONS = {
    "run_without_phase_png": (["run", "--out", "{out}", "--set", 'output.plots=["gap","psd","forces"]'], 1.5),
    "run_vtu_every_20": (["run", "--out", "{out}", "--set", "output.vtu_every=20"], 1.5),
    "run_without_vtu": (["run", "--out", "{out}", "--set", "output.vtu_every=0"], 1.5),
    "run_without_plots": (["run", "--out", "{out}", "--set", "output.plots=[]"], 1.5),
}
#: modules that only drawing, rendering, sweeping, writing VTU or a PSD / rk / penalty should import
HEAVY = ("matplotlib", "pyvista", "vtk", "dask", "distributed", "meshio", "scipy.signal", "scipy.integrate",
         "scipy.optimize")

#: the child of ``--breakdown``: the parts of ``nsfem run`` (as cli._run does them) timed in one interpreter
BREAKDOWN = r"""
import json, sys, time
parts = {}
def lap(name, t):
    w, c = time.perf_counter(), time.process_time()
    parts[name] = {"wall_s": w - t[0], "cpu_s": c - t[1]}
    t[:] = [w, c]
t = [time.perf_counter(), time.process_time()]
from nsfem.cli import one_blas_thread
one_blas_thread()   # as the command does
from pathlib import Path
from nsfem.fem.constraints import dense
from nsfem.scene import load_scene
from nsfem.simulate import run_scene
lap("imports (scene, model, integrators)", t)
scene = load_scene(None, [])
result, system = run_scene(scene, scene.simulation.method)
lap("model, reduction and integration", t)
parts["of which the integration"] = {"wall_s": result.wall_s}
out = Path(sys.argv[1])
result.save(out / "result.npz", "", dense(system.info["reduction"].T), system.model_contacts.x, scene.record())
lap("results file", t)
import matplotlib
matplotlib.use("Agg")
import matplotlib.figure, matplotlib.backends.backend_agg
from nsfem.plot.results import PLOT_FUNCTIONS
lap("matplotlib import", t)
for name in scene.output.plots:
    if name in PLOT_FUNCTIONS:
        PLOT_FUNCTIONS[name](result, system, out / f"{name}.png")
        lap(f"{name}.png", t)
from nsfem.export.vtu import write_series
write_series(result, system, out, every=scene.output.vtu_every)
lap(f"VTU series (every {scene.output.vtu_every}: {len(list(out.glob('**/*.vtu')))} files)", t)
print(json.dumps(parts))
"""

#: the child that lists the heavy modules a command imported
IMPORTED = r"""
import json, runpy, sys
sys.argv = ["nsfem"] + json.loads(sys.argv[1])
try:
    runpy.run_module("nsfem", run_name="__main__", alter_sys=True)
except SystemExit:
    pass
print(json.dumps(sorted(m for m in sys.modules if m in HEAVY)), file=sys.__stderr__)
"""


def _env(tree: Path = ROOT) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return {**env, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}


def _argv(name: str, out: str) -> list[str]:
    return [a.replace("{out}", out) for a in {**COMMANDS, **OPTIONS}[name][0]]


def one(name: str, out: str, tree: Path = ROOT) -> dict:
    """One fresh ``python -m nsfem`` command on ``tree``'s sources: wall time, CPU time of the child."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "nsfem", *_argv(name, out)], env=_env(tree), cwd=tree,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if run.returncode:
        raise SystemExit(f"latency: {name} failed ({run.returncode}): "
                         + (run.stderr.strip().splitlines() or ["?"])[-1])
    return {"wall_s": wall, "cpu_s": cpu}


def imported(name: str, out: str) -> list[str]:
    """The modules of :data:`HEAVY` that the command ``name`` imported."""
    code = IMPORTED.replace("HEAVY", repr(HEAVY))
    run = subprocess.run([sys.executable, "-c", code, json.dumps(_argv(name, out))], env=_env(), cwd=ROOT,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, check=True)
    return json.loads(run.stderr.strip().splitlines()[-1])


def breakdown(out: str) -> dict:
    """The parts of the whole ``nsfem run`` timed in one fresh interpreter (:data:`BREAKDOWN`)."""
    Path(out).mkdir(parents=True, exist_ok=True)
    run = subprocess.run([sys.executable, "-c", BREAKDOWN, out], env=_env(), cwd=ROOT, capture_output=True,
                         text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def base_tree(commit: str, folder: Path) -> tuple[Path, str]:
    """``commit``'s sources in ``folder`` and which event core they run: this tree's compiled one when the
    core's sources are unchanged since ``commit`` (and built here), else pure Python."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], capture_output=True, check=True)
    folder.mkdir(parents=True)
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    core = ROOT / "nsfem" / "integrate" / "core"
    same = subprocess.run(["git", "-C", str(ROOT), "diff", "--quiet", commit, "--", str(core)]).returncode == 0
    built = sorted(core.glob("_*.so"))
    if not (same and built):
        return folder, "python"
    for so in built:
        shutil.copy2(so, folder / "nsfem" / "integrate" / "core" / so.name)
    return folder, "compiled (this tree's build)"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 rounds")
    ap.add_argument("--json", action="store_true", help="print one JSON object (progress to stderr)")
    ap.add_argument("--repeat", type=int, default=None, help="rounds (7; --quick 3)")
    ap.add_argument("--breakdown", action="store_true", help="also time the whole run's parts and list the "
                    "heavy modules each command imports")
    ap.add_argument("--base", metavar="COMMIT", help="also time that commit's sources, round by round")
    ap.add_argument("--options", action="store_true", help="also the whole run with one default changed "
                    "(no phase.png, VTU every 20, no VTU, no plots), this tree only")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "latency"))
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr if args.json else sys.stdout, flush=True)
    repeat = args.repeat or (3 if args.quick else 7)
    if repeat < 1:
        ap.error(f"--repeat: {repeat} rounds; give at least 1")
    extra: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this": (ROOT, "this tree")}
        if args.base:
            folder, core = base_tree(args.base, Path(tmp) / "base")
            trees["base"] = (folder, f"{args.base} (event core: {core})")
        commands = {**COMMANDS, **(OPTIONS if args.options else {})}
        runs = [(name, label) for name in commands for label in trees if label == "this" or name in COMMANDS]
        times = {(label, name): [] for name, label in runs}
        for k in range(repeat + 1):   # round 0 untimed: bytecode and file caches
            for name, label in runs:
                r = one(name, str(Path(tmp) / f"{label}_{name}_{k}"), trees[label][0])
                if k:
                    times[label, name].append(r)
        if args.breakdown:
            extra["breakdown"] = breakdown(str(Path(tmp) / "breakdown"))
            extra["imported"] = {name: imported(name, str(Path(tmp) / f"imported_{name}")) for name in COMMANDS}
    rows = []
    for name, (_, goal) in commands.items():
        for label, (_, about) in trees.items():
            if (label, name) not in times:
                continue
            walls = [r["wall_s"] for r in times[label, name]]
            cpus = [r["cpu_s"] for r in times[label, name]]
            rows.append({"command": "nsfem " + " ".join(_argv(name, "DIR")), "name": name, "tree": about,
                         "goal_s": goal, "min_wall_s": min(walls), "median_wall_s": statistics.median(walls),
                         "median_cpu_s": statistics.median(cpus), "met": min(walls) <= goal})
    for r in rows:
        say(f"{r['command']}\n    {r['tree']}: fastest {r['min_wall_s']:.3f} s, median {r['median_wall_s']:.3f} s "
            f"wall, median {r['median_cpu_s']:.3f} s CPU (goal {r['goal_s']} s: {'met' if r['met'] else 'NOT met'})")
    for part, v in extra.get("breakdown", {}).items():
        say(f"  {part:42s} {v['wall_s']:.3f} s" + (f" wall, {v['cpu_s']:.3f} s CPU" if "cpu_s" in v else ""))
    for name, mods in extra.get("imported", {}).items():
        say(f"  {name} imports: {', '.join(mods) or 'none of ' + ', '.join(HEAVY)}")
    payload = {"repeat": repeat, "commands": rows, **extra,
               "all_met": all(r["met"] for r in rows if r["tree"] == "this tree" and r["name"] in COMMANDS),
               "machine": {**machine(), "load_average": os.getloadavg()}}
    write_outputs(Path(args.out), "latency", rows, payload)
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
