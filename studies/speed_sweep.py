"""Speed sweep of the shipped scene: where does the delamination gap close?

The shipped scene (undamped unless ``--rayleigh ALPHA``) is run from its stationary state
(``initial.state = "stationary"``: the centrifugal opening, LCP 28) for ``t_end`` at speeds from
10 to 90 Hz, finer around the gravity resonances below 90 Hz (from the library's campbell
analysis, open contacts). Each speed is one run of ``nsfem.sweep.run_sweep`` on a Dask
LocalCluster; the coarse and the fine ranges are sweeps into one folder (same swept key and
fixed settings, so the later ones resume the earlier ones' runs). Also measured in the same
script run: runs per second with 1 and with 2 worker processes on a small subset (cluster
start excluded, and included).

    python studies/speed_sweep.py [--quick] [--json] [--t-end T] [--rayleigh ALPHA] [--out DIR]

Writes speed_sweep.csv/.json and speed_sweep.png into studies/out/speed_sweep (the runs under
runs/), and copies the figure to docs/figures/speed_sweep.png. --quick: coarser speeds,
t_end = 0.5 s (about 3 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.analysis.campbell import campbell_report
from nsfem.fem.assemble import build_model
from nsfem.plot.sweep import plot_resonance
from nsfem.reduce import scene_reduction
from nsfem.sweep import run_sweep

ROOT = Path(__file__).resolve().parents[1]
KEY = "rotation.speed_hz"


def resonances(fixed: list[str]) -> tuple[list[float], list[list[float]]]:
    """(gravity resonances [Hz] of the open linearization, divergence bands [[a, b]]) below 90 Hz."""
    scene = load_scene(None, fixed)
    model = build_model(scene)
    rep = campbell_report(scene, model, [0.0], 6, scene_reduction(scene, model))
    res = [x for x in rep["gravity_resonances_hz"]["open"] if x is not None and x <= 90.0]
    bands = [[a, min(b if b is not None else 90.0, 90.0)] for a, b in rep["instability_bands_hz"]["open"] if a <= 90.0]
    return res, bands


def ranges(quick: bool, res: list[float]) -> list[str]:
    """The coarse range, then one fine range around each gravity resonance."""
    out = [f"{KEY}=10:90:{17 if quick else 41}"]
    half, n = (1.0, 5) if quick else (2.0, 17)
    for r in res:
        out.append(f"{KEY}={r - half:.4f}:{r + half:.4f}:{n}")
    return out


def throughput(fixed: list[str], subset: str, workers: int) -> dict:
    """Runs per second of a fresh LocalCluster of ``workers`` processes on ``subset`` (a range)."""
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=50) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        client.run(__import__, "nsfem.simulate")  # imports are part of the start, not of the runs
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            res = run_sweep(None, fixed + [subset], tmp, client=client, plot=False)
        t2 = time.perf_counter()
    n = len(res.runs)
    return {"workers": workers, "runs": n, "wall_s": t2 - t1, "runs_per_s": n / (t2 - t1),
            "with_startup_s": t2 - t0, "runs_per_s_with_startup": n / (t2 - t0), "failed": len(res.failed),
            "load_average_1min": os.getloadavg()[0]}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarser speeds, t_end 0.5 s (about 3 minutes)")
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    ap.add_argument("--t-end", type=float, help="simulated time per run [s] (default 1, --quick 0.5)")
    ap.add_argument("--rayleigh", type=float, default=0.0, metavar="ALPHA",
                    help="mass-proportional damping alpha [1/s] (default 0: the shipped scene)")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--out", default="studies/out/speed_sweep")
    args = ap.parse_args(argv)
    # with --json, stdout holds the JSON object only: the report goes to stderr
    say = functools.partial(print, file=sys.stderr) if args.json else print
    out = Path(args.out)
    t_end = args.t_end or (0.5 if args.quick else 1.0)
    fixed = ['initial.state="stationary"', f"simulation.t_end={t_end:g}"]
    if args.rayleigh:
        fixed.append(f"damping.rayleigh=[{args.rayleigh:g}, 0.0]")
    res, bands = resonances(fixed)
    tag = f"t{t_end:g}" + (f"_alpha{args.rayleigh:g}" if args.rayleigh else "")
    runs_dir = out / "runs" / tag

    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    rows: dict[float, dict] = {}
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=50) as cluster, Client(cluster) as client:
        for rng in ranges(args.quick, res):
            sw = run_sweep(None, fixed + [rng], runs_dir, client=client, plot=False,
                           progress=lambda line: say(line, flush=True))
            rows.update({float(r[KEY]): r for r in sw.runs if r is not None})
    sweep_wall = time.perf_counter() - t0
    table = [rows[s] for s in sorted(rows)]
    subset = f"{KEY}=10:40:{8 if args.quick else 16}"  # below the divergence bands: similar run times
    speed = [throughput(fixed, subset, w) for w in (1, 2)]

    ok = [r for r in table if not r["error"]]
    closed = [r for r in ok if r["closed_fraction"] > 0]
    peak = max(ok, key=lambda r: r["closed_fraction"]) if ok else None
    near = min(ok, key=lambda r: r["min_gap_m"]) if ok else None
    near_open = min((r for r in ok if not any(a <= r[KEY] <= b for a, b in bands)), key=lambda r: r["min_gap_m"],
                    default=None)
    findings = {
        "gravity_resonances_hz": res, "divergence_bands_hz": bands,
        "closing_speeds_hz": [r[KEY] for r in closed],
        "closed_fraction_peak": None if peak is None else {"speed_hz": peak[KEY], "closed_fraction":
                                                           peak["closed_fraction"]},
        "smallest_min_gap": None if near is None else {"speed_hz": near[KEY], "min_gap_m": near["min_gap_m"]},
        "smallest_min_gap_outside_bands": None if near_open is None else
        {"speed_hz": near_open[KEY], "min_gap_m": near_open["min_gap_m"]},
        "failed": [{"speed_hz": r[KEY], "error": r["error"]} for r in table if r["error"]],
    }
    fig = plot_resonance(out / "speed_sweep.png", [KEY], [{KEY: r[KEY]} for r in table], table,
                         f"shipped scene from its stationary state, t_end = {t_end:g} s"
                         + (f", alpha = {args.rayleigh:g} 1/s" if args.rayleigh else ", undamped"), dpi=100,
                         marks={"gravity resonance": res}, bands=bands)
    docs_fig = ROOT / "docs" / "figures" / "speed_sweep.png"
    if not args.quick or not docs_fig.exists():
        shutil.copyfile(fig, docs_fig)
    payload = {"t_end": t_end, "rayleigh_alpha": args.rayleigh, "quick": args.quick, "runs": len(table),
               "sweep_wall_s": sweep_wall, "workers": args.workers, "throughput": speed, "findings": findings,
               "machine": machine(), "runs_dir": str(runs_dir)}
    write_outputs(out, "speed_sweep", [{k: v for k, v in r.items() if k != "warnings"} for r in table], payload)
    say(f"{len(table)} speeds in {sweep_wall:.1f} s on {args.workers} workers; gravity resonances "
          + ", ".join(f"{x:.2f}" for x in res) + " Hz; divergence bands "
          + ", ".join(f"{a:.2f}-{b:.2f}" for a, b in bands) + " Hz")
    say("gap closes at: " + (", ".join(f"{r[KEY]:g} Hz ({100 * r['closed_fraction']:.1f} %)" for r in closed)
                               or "no speed"))
    if near_open:
        say(f"smallest gap outside the divergence bands: {near_open['min_gap_m']:.3e} m at {near_open[KEY]:g} Hz")
    for s in speed:
        say(f"{s['workers']} worker(s): {s['runs']} runs in {s['wall_s']:.2f} s = {s['runs_per_s']:.2f} runs/s "
              f"({s['runs_per_s_with_startup']:.2f} runs/s with the cluster start; load average "
              f"{s['load_average_1min']:.1f} on {os.cpu_count()} cores)")
    say(f"wrote {out}/speed_sweep.csv, .json, {fig}")
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
