"""Error against run time for every integrator (``exact``, ``rk``, ``penalty``, ``moreau``).

Two scenes: the shipped one (21 Hz, near its first gravity resonance, started from rest: the
interface touches at midspan each period) and an impact-dominated one (the shipped shaft with
a stop 0.2 mm under midspan, restitution 0.5: Zeno-like impact sequences every revolution).

Error of a run = max over contacts and output times of |g - g_ref| / max |g_ref|: the gap
history at the output times, the quantity users plot. The reference is ``exact`` (closed form
between events); its own error is bounded by its distance to ``rk`` at rtol 1e-12, which is
reported. Each method runs at several settings (rk: rtol; penalty: contact stiffness factor and
tolerance; moreau: step); its curve is the lower-left (Pareto) front of its (wall, error)
points. All ratios below are a method's wall time over exact's (> 1: exact is faster):

- ``speedup_at_equal_error``: the wall time the method needs to reach exact's error (log-log
  interpolation on its curve) over exact's wall time. Null for a method that never reaches
  exact's error: no setting gives an answer as good, so there is no equal-error ratio.
- ``speedup_at_own_best_error`` (only for those methods, flagged "never reached"): the wall
  time of the method's best (most accurate) point over exact's wall time, with that best error
  next to exact's. Exact's error is the better of the two, so this ratio flatters the method.
- ``fastest_any_answer``: the fastest wall time any non-exact method took to give any answer
  at all (with its error, however large) against exact's wall time for its certified one; the
  goal of issue 17 is that no method answers faster than exact (``exact_is_fastest``).
- ``exact_ms_per_event``: exact's wall time over its number of events (impacts, closures,
  releases): all of it, the search between events included.

    python studies/work_precision.py [--quick] [--json] [--scene shipped|stop|both]

Writes work_precision.csv/.json and work_precision_<scene>.png into studies/out/work_precision;
``--json`` prints one object {"points": {method: [[error, wall_s], ...]}, "speedup_at_equal_error":
{...}, "speedup_at_own_best_error": {...}, "fastest_any_answer": {...}, "exact_ms_per_event": ...,
...} (for the shipped scene; the stop scene under "stop").
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.fem.assemble import build_model
from nsfem.integrate import ContactSystem, integrate
from nsfem.reduce import scene_reduction
from nsfem.simulate import initial_state

SCENES = {
    "shipped": [],
    "stop": ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]'],
}


def settings(quick: bool) -> list[tuple[str, dict]]:
    rk = [1e-6, 1e-8, 1e-10] if quick else [1e-6, 1e-8, 1e-10, 1e-12]
    pen = [(1e1, 1e-6), (1e2, 1e-6), (1e3, 1e-8)] if quick else \
        [(1e1, 1e-6), (1e2, 1e-6), (1e2, 1e-8), (1e3, 1e-8), (1e4, 1e-8)]
    mor = [10, 40] if quick else [10, 40, 160, 640]
    out = [("exact", {})]
    out += [("rk", {"rtol": r, "atol": r * 1e-4}) for r in rk]
    out += [("penalty", {"factor": f, "rtol": r, "atol": r * 1e-4}) for f, r in pen]
    out += [("moreau", {"substeps": s}) for s in mor]
    return out


def front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The (error, wall) points no other point beats in both, sorted by wall time."""
    pts = sorted(points, key=lambda p: (p[1], p[0]))
    out, best = [], np.inf
    for e, w in pts:
        if e < best:
            out.append((e, w))
            best = e
    return out


def wall_at(curve: list[tuple[float, float]], target: float) -> tuple[float, bool]:
    """Wall time on a (Pareto) curve at error ``target``; (wall of the best point, True) if never reached."""
    for i, (e, w) in enumerate(curve):
        if e <= target:
            if i == 0:
                return w, False
            (e0, w0) = curve[i - 1]
            x = (np.log(target) - np.log(e0)) / (np.log(e) - np.log(e0))
            return float(np.exp(np.log(w0) + x * (np.log(w) - np.log(w0)))), False
    return curve[-1][1], True


def study(scene_name: str, t_end: float, quick: bool) -> tuple[dict, list[dict]]:
    scene = load_scene(None, SCENES[scene_name] + [f"simulation.t_end={t_end}"])
    model = build_model(scene)
    red = scene_reduction(scene, model)
    system = ContactSystem.from_scene(scene, model, red)
    dt = scene.simulation.output_dt
    q0, v0 = initial_state(scene, model, red, system)

    def run(method, opts):
        kw = dict(opts)
        if method == "moreau":
            kw = {"step": dt / kw.pop("substeps")}
        t0 = time.perf_counter()
        res = integrate(system, t_end, method, dt, q0, v0, **kw)
        return res, time.perf_counter() - t0

    ref, wall_exact = run("exact", {})
    wall_exact = min(wall_exact, run("exact", {})[1])  # the machine is shared: best of two
    check, _ = run("rk", {"rtol": 1e-12, "atol": 1e-16})
    gmax = float(np.abs(ref.gap).max())
    exact_error = max(float(np.abs(check.gap - ref.gap).max()) / gmax, 1e-16)
    rows = [{"scene": scene_name, "method": "exact", "setting": "default", "wall_s": wall_exact,
             "error": exact_error, "events": len(ref.events), "impacts": len(ref.impacts)}]
    points: dict[str, list] = {"exact": [[exact_error, wall_exact]]}
    for method, opts in settings(quick)[1:]:
        try:
            res, wall = run(method, opts)
            err = float(np.abs(res.gap - ref.gap).max()) / gmax
        except Exception as exc:  # a setting that fails is a data point too
            rows.append({"scene": scene_name, "method": method, "setting": json.dumps(opts), "wall_s": None,
                         "error": None, "failure": str(exc)[:200]})
            continue
        rows.append({"scene": scene_name, "method": method, "setting": json.dumps(opts), "wall_s": wall,
                     "error": err, "events": len(res.events), "impacts": len(res.impacts),
                     "max_penetration_m": float(max(-res.gap.min(), 0.0))})
        points.setdefault(method, []).append([err, wall])
    speedup, own_best, flags = {}, {}, {}
    for method, pts in points.items():
        if method == "exact":
            continue
        curve = front([tuple(p) for p in pts])
        wall, flag = wall_at(curve, exact_error)
        flags[method] = flag
        if flag:  # never as good as exact: no equal-error ratio; the ratio at its own best error instead
            best_error, best_wall = min(curve)
            speedup[method] = None
            own_best[method] = {"speedup": best_wall / wall_exact, "best_error": best_error,
                                "wall_s": best_wall, "exact_error": exact_error}
        else:
            speedup[method] = wall / wall_exact
    answered = [r for r in rows if r["method"] != "exact" and r.get("wall_s") is not None]
    fastest = None
    if answered:
        r = min(answered, key=lambda r: r["wall_s"])
        fastest = {"method": r["method"], "setting": r["setting"], "wall_s": r["wall_s"], "error": r["error"],
                   "exact_wall_s": wall_exact, "exact_error": exact_error,
                   "speedup": r["wall_s"] / wall_exact, "exact_is_fastest": wall_exact <= r["wall_s"]}
    events = len(ref.events)
    payload = {"scene": scene_name, "t_end": t_end, "exact_error_bound": exact_error,
               "exact_wall_s": wall_exact, "exact_events": events,
               "exact_ms_per_event": 1e3 * wall_exact / events if events else None,
               "points": points, "speedup_at_equal_error": speedup,
               "speedup_at_own_best_error": own_best, "never_reached_exact_error": flags,
               "fastest_any_answer": fastest}
    return payload, rows


def plot(payload: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for method, pts in payload["points"].items():
        pts = sorted(pts, key=lambda p: p[1])
        e, w = np.array(pts).T
        ax.loglog(w, e, "o-" if len(pts) > 1 else "*", label=method, ms=8 if method == "exact" else 5)
    ax.set_xlabel("wall time [s] (one core)")
    ax.set_ylabel("max gap error / max gap")
    ax.set_title(f"work-precision, {payload['scene']} scene, {payload['t_end']:g} s simulated")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="0.2 s simulated, fewer settings (< 10 min on 2 cores)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--scene", choices=("shipped", "stop", "both"), default="both")
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "work_precision"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = ["shipped", "stop"] if args.scene == "both" else [args.scene]
    results, rows = {}, []
    for name in names:
        t_end = args.t_end or ((0.2 if args.quick else 1.0) if name == "shipped" else (0.05 if args.quick else 0.2))
        payload, r = study(name, t_end, args.quick)
        results[name] = payload
        rows += r
        plot(payload, out / f"work_precision_{name}.png")
    main_payload = dict(results.get("shipped") or results[names[0]])
    if "stop" in results and "shipped" in results:
        main_payload["stop"] = results["stop"]
    main_payload["machine"] = machine()
    write_outputs(out, "work_precision", rows, main_payload)
    if args.json:
        print(json.dumps(main_payload))
    else:
        for r in rows:
            err = "-" if r.get("error") is None else f"{r['error']:.2e}"
            wall = "-" if r.get("wall_s") is None else f"{r['wall_s']:.3f}"
            print(f"{r['scene']:8s} {r['method']:8s} {r['setting']:45s} wall {wall:>9s} s  error {err}"
                  + (f"  FAILED: {r['failure']}" if r.get("failure") else ""))
        for name, p in results.items():
            per_event = "-" if p["exact_ms_per_event"] is None else f"{p['exact_ms_per_event']:.3g} ms per event"
            print(f"{name}: exact {p['exact_wall_s']:.3g} s, {p['exact_events']} events ({per_event}), "
                  f"error bound {p['exact_error_bound']:.2g}; method wall / exact wall (> 1: exact faster):")
            for m, x in p["speedup_at_equal_error"].items():
                if x is not None:
                    print(f"  {m:8s} at equal error: {x:.3g}")
                else:
                    b = p["speedup_at_own_best_error"][m]
                    print(f"  {m:8s} NEVER reaches exact's error {b['exact_error']:.2g}; at its own best error "
                          f"{b['best_error']:.2g} (worse than exact's): {b['speedup']:.3g}")
            f = p["fastest_any_answer"]
            if f is not None:
                print(f"  fastest answer of any other method: {f['method']} {f['setting']} {f['wall_s']:.3g} s "
                      f"(error {f['error']:.2g}) against exact {f['exact_wall_s']:.3g} s: {f['speedup']:.3g}"
                      + ("" if f["exact_is_fastest"] else "  (FASTER THAN EXACT)"))
    return main_payload


if __name__ == "__main__":
    main()
