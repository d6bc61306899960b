"""Which method gives any answer first on the unreduced shipped scene (issue 17's goal, restated in issue 33).

The shipped scene (``nsfem/scenes/default.toml``: 40 elements, 355 dofs) with ``reduction.method = "none"``,
3 s from rest, integrated by every method on that same model: ``exact`` at its only setting, ``rk``,
``moreau`` and ``penalty`` each at their default setting and at a loose one (the fastest answer each can
give at all: rk rtol 1e-4, moreau one step per output interval, penalty factor 10 and rtol 1e-3). Each run
is its own process with a time budget (a run over budget is killed and recorded as ``timeout``: it gave no
answer within the budget; the budget is far above exact's time, so it answered later than exact did). The
model and the initial state are built once per process and timed apart; the ratio compared is the
integration's wall time over exact's, measured in the same run one after the other. Each answer's error is
max |g - g_exact| / max |g_exact| over the contacts and output times (the gap histories users plot).

    python studies/unreduced.py [--quick] [--json] [--t-end T] [--budget S] [--out DIR]

``--quick``: the default and the loose setting of each method as above, budget 120 s per run (the full
study adds rk rtol 1e-6 and moreau 100 steps per output interval, budget 600 s). The simulated time is 3 s
in both (the goal's case). Writes unreduced.csv/.json into studies/out/unreduced; ``--json`` prints one
object {"runs": [...], "exact_wall_s", "fastest_other": {...}, "exact_is_fastest", ...}.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import multiprocessing as mp
import queue
import sys
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

OVERRIDES = ['reduction.method="none"']


def settings(quick: bool) -> list[tuple[str, str, dict]]:
    """(method, label, options) in the order they run; exact first (the reference)."""
    out = [("exact", "default", {}),
           ("rk", "default (rtol 1e-8)", {}), ("rk", "rtol 1e-4", {"rtol": 1e-4, "atol": 1e-8}),
           ("moreau", "default (10 steps per output)", {}), ("moreau", "1 step per output", {"substeps": 1}),
           ("penalty", "default (factor 100, rtol 1e-6)", {}),
           ("penalty", "factor 10, rtol 1e-3", {"factor": 10.0, "rtol": 1e-3, "atol": 1e-7})]
    if not quick:
        out += [("rk", "rtol 1e-6", {"rtol": 1e-6, "atol": 1e-10}),
                ("moreau", "100 steps per output", {"substeps": 100})]
    return out


def _work(method: str, options: dict, t_end: float, channel) -> None:
    """One run in its own process: set-up, then the integration; results go to ``channel``."""
    try:
        from nsfem import load_scene
        from nsfem.fem.assemble import build_model
        from nsfem.integrate import ContactSystem, core, integrate
        from nsfem.reduce import scene_reduction
        from nsfem.simulate import initial_state

        t0 = time.perf_counter()
        scene = load_scene(None, OVERRIDES + [f"simulation.t_end={t_end}"])
        model = build_model(scene)
        red = scene_reduction(scene, model)
        system = ContactSystem.from_scene(scene, model, red)
        q0, v0 = initial_state(scene, model, red, system)
        dt = scene.simulation.output_dt
        channel.put({"ndof": system.n, "setup_s": time.perf_counter() - t0})
        kw = dict(options)
        if method == "moreau" and "substeps" in kw:
            kw = {"step": dt / kw.pop("substeps")}
        t1 = time.perf_counter()
        res = integrate(system, t_end, method, dt, q0, v0, **kw)
        wall = time.perf_counter() - t1
        channel.put({"status": "ok", "wall_s": wall, "events": len(res.events), "impacts": len(res.impacts),
                     "completed": bool(res.completed), "gap": res.gap.tolist(),
                     "max_penetration_m": float(max(-res.gap.min(), 0.0)), "core": core.name()})
    except BaseException as exc:  # noqa: BLE001 - a failing run is a data point
        channel.put({"status": "error", "error": f"{type(exc).__name__}: {exc}"[:300]})


def run_one(method: str, label: str, options: dict, t_end: float, budget: float) -> dict:
    """``method`` in a fresh process, killed after ``budget`` seconds of integration (status ``timeout``)."""
    ctx = mp.get_context("spawn")
    channel = ctx.Queue()
    proc = ctx.Process(target=_work, args=(method, options, t_end, channel), daemon=True)
    row: dict = {"method": method, "setting": label, "options": json.dumps(options), "t_end": t_end}
    deadline = None
    proc.start()
    while "status" not in row:
        now = time.perf_counter()
        if deadline is not None and now >= deadline:
            break
        try:
            row.update(channel.get(timeout=1.0 if deadline is None else max(min(deadline - now, 1.0), 0.01)))
            if "setup_s" in row and deadline is None:   # the budget is the integration's
                deadline = time.perf_counter() + budget
        except queue.Empty:
            if not proc.is_alive():
                with contextlib.suppress(queue.Empty):
                    row.update(channel.get(timeout=1.0))
                row.setdefault("status", "error")
                row.setdefault("error", f"process ended with exit code {proc.exitcode}")
    if "status" not in row:
        proc.kill()
        row["status"] = "timeout"
        row["wall_s_at_least"] = budget
    proc.join(10)
    channel.close()
    row["budget_s"] = budget
    return row


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="default and loose settings only, budget 120 s per run")
    ap.add_argument("--json", action="store_true", help="print one JSON object (progress to stderr)")
    ap.add_argument("--t-end", type=float, default=3.0, help="simulated time [s] (default 3, the goal's case)")
    ap.add_argument("--budget", type=float, default=None, help="integration seconds per run (120 quick, 600 full)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "unreduced"))
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr if args.json else sys.stdout, flush=True)
    budget = args.budget or (120.0 if args.quick else 600.0)
    rows = []
    ref = None
    for method, label, options in settings(args.quick):
        say(f"{method} {label} ...")
        r = run_one(method, label, options, args.t_end, budget)
        gap = r.pop("gap", None)
        if method == "exact" and gap is not None:
            ref = np.asarray(gap)
        elif gap is not None and ref is not None:
            g = np.asarray(gap)
            n = min(g.shape[1], ref.shape[1])
            r["gap_error"] = float(np.abs(g[:, :n] - ref[:, :n]).max() / np.abs(ref[:, :n]).max())
        rows.append(r)
        say(f"  {r['status']}: " + (f"{r['wall_s']:.2f} s, {r['events']} events" if r["status"] == "ok" else
                                     r.get("error", f"no answer within {budget:g} s"))
            + (f", gap error {r['gap_error']:.2e}" if "gap_error" in r else ""))
    exact = rows[0]
    others = [r for r in rows[1:] if r["status"] == "ok"]
    fastest = min(others, key=lambda r: r["wall_s"]) if others else None
    ew = exact.get("wall_s")
    for r in rows[1:]:
        if ew and r["status"] == "ok":
            r["wall_over_exact"] = r["wall_s"] / ew
        elif ew and r["status"] == "timeout":
            r["wall_over_exact_at_least"] = budget / ew
    payload = {"quick": args.quick, "t_end": args.t_end, "overrides": OVERRIDES, "budget_s": budget,
               "ndof": exact.get("ndof"), "exact_wall_s": ew, "exact_events": exact.get("events"),
               "exact_ms_per_event": 1e3 * ew / exact["events"] if ew and exact.get("events") else None,
               "runs": rows,
               "fastest_other": None if fastest is None else
               {k: fastest.get(k) for k in ("method", "setting", "wall_s", "gap_error", "wall_over_exact")},
               "exact_is_fastest": bool(ew is not None and (fastest is None or ew <= fastest["wall_s"])),
               "machine": machine()}
    write_outputs(Path(args.out), "unreduced", rows, payload)
    say(f"unreduced shipped scene ({payload['ndof']} dofs), {args.t_end:g} s from rest; integration wall time "
        f"over exact's ({ew:.2f} s, {exact.get('events')} events) side by side (> 1: exact first):"
        if ew else "exact gave no answer")
    for r in rows[1:]:
        ratio = (f"{r['wall_over_exact']:.3g}" if "wall_over_exact" in r else
                 f"> {r['wall_over_exact_at_least']:.3g} (timeout)" if "wall_over_exact_at_least" in r else r["status"])
        say(f"  {r['method']:8s} {r['setting']:34s} {ratio:>16s}"
            + (f"  gap error {r['gap_error']:.2e}" if "gap_error" in r else ""))
    say("exact gives its answer first" if payload["exact_is_fastest"] else
        f"FASTER THAN EXACT: {fastest['method']} {fastest['setting']}")
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
