"""``exact`` against ``rk`` on the shipped scene, side by side in one run.

Error = max over contacts and output times of |gap - gap_ref| / max|gap_ref| (plus the
relative difference of the contact impulses), with the reference computed by ``exact``
(closed form between events; its own error is checked against ``rk`` at the tightest
tolerance, which must agree within that tolerance's error). The speed-up is the wall time
``rk`` needs to reach the error of ``exact`` (log-log interpolation on its curve; when it
never gets there, the ratio at its best error, flagged) divided by the wall time of
``exact``. Real-time factor = simulated seconds per wall second.

    python studies/integrator_benchmark.py [--quick] [--json] [--t-end T]

Writes integrator_benchmark.json/.csv into studies/out/integrator_benchmark.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.integrate import ContactSystem, integrate


def impulses(res) -> float:
    return float(sum(sum(i["impulse_Ns"]) for i in res.impacts))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="0.2 s simulated, three rk tolerances")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "integrator_benchmark"))
    args = ap.parse_args(argv)
    t_end = args.t_end or (0.2 if args.quick else 1.0)
    rtols = [1e-6, 1e-8, 1e-10] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    scene = load_scene(None, [])
    system = ContactSystem.from_scene(scene)
    dt = scene.simulation.output_dt

    def run(method, **kw):
        t0 = time.perf_counter()
        res = integrate(system, t_end, method, dt, **kw)
        return res, time.perf_counter() - t0

    ref, wall_exact = run("exact")
    ref2, wall_exact2 = run("exact")  # a second timing: the machine is shared
    wall_exact = min(wall_exact, wall_exact2)
    gmax = np.abs(ref.gap).max()
    rows = [{"method": "exact", "rtol": None, "wall_s": wall_exact, "events": len(ref.events),
             "impacts": len(ref.impacts), "error": None, "impulse_error": 0.0}]
    for rtol in rtols:
        res, wall = run("rk", rtol=rtol, atol=rtol * 1e-4)
        err = float(np.abs(res.gap - ref.gap).max() / gmax)
        ierr = abs(impulses(res) - impulses(ref)) / max(impulses(ref), 1e-300)
        rows.append({"method": "rk", "rtol": rtol, "wall_s": wall, "events": len(res.events),
                     "impacts": len(res.impacts), "error": err, "impulse_error": ierr})
    rk = [r for r in rows if r["method"] == "rk"]
    # exact's own error: bounded by its distance to the tightest rk plus that rk's error estimate
    tight = rk[-1]
    exact_error = max(tight["error"], 1e-15)
    rows[0]["error"] = exact_error
    errs = np.array([r["error"] for r in rk])
    walls = np.array([r["wall_s"] for r in rk])
    reached = errs <= exact_error * 1.0001
    if reached.any():
        i = int(np.argmax(reached))
        if i == 0:
            wall_needed = walls[0]
        else:  # log-log interpolation between the last miss and the first hit
            x0, x1 = np.log(errs[i - 1]), np.log(errs[i])
            y0, y1 = np.log(walls[i - 1]), np.log(walls[i])
            wall_needed = float(np.exp(y0 + (np.log(exact_error) - x0) * (y1 - y0) / (x1 - x0)))
        flag = False
    else:
        wall_needed, flag = float(walls[np.argmin(errs)]), True
    payload = {
        "scene": "shipped (21 Hz, CB-16, 25 dofs, 9 contacts, start from rest)", "t_end": t_end,
        "exact": {"wall_s": wall_exact, "realtime_factor": t_end / wall_exact, "events": len(ref.events),
                  "impacts": len(ref.impacts), "error_bound": exact_error,
                  "energy_residual": ref.energy["relative_residual"]},
        "rk": rk,
        "speedup_vs_rk_at_equal_error": wall_needed / wall_exact,
        "rk_never_reached_exact_error": flag,
        "machine": machine(),
    }
    out = Path(args.out)
    write_outputs(out, "integrator_benchmark", rows, payload)
    if args.json:
        print(json.dumps(payload))
    else:
        for r in rows:
            print(f"{r['method']:6s} rtol {r['rtol'] or '-':>8}  wall {r['wall_s']:8.3f} s  events {r['events']:4d}  "
                  f"impacts {r['impacts']:4d}  gap error {r['error']:.2e}  impulse error {r['impulse_error']:.1e}")
        print(f"exact: {payload['exact']['realtime_factor']:.2f} simulated s per wall s; speed-up against rk at "
              f"equal error: {payload['speedup_vs_rk_at_equal_error']:.1f}x" + (" (rk never reached it)" if flag
                                                                                 else ""))
    return payload


if __name__ == "__main__":
    main()
