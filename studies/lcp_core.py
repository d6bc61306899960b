"""The compiled Lemke (event core part "lcp", issue 33) against its Python reference, side by side.

In one process, both paths (the reference through ``core.reference()``), best of ``--repeat``, alternating:

- ``kernel``: :func:`nsfem.lcp.lemke` alone on the LCPs an exact run of the stop scene (and of the stop
  scene with friction) solves (recorded with their keywords: cached scalings, groups), per LCP and per
  event of the run, and on random frictional contact LCPs of 1 to 4 contacts (r = 4 generators: 6
  unknowns per contact);
- ``end_to_end``: ``run_scene(scene, "exact")`` on the stop scene (the shipped shaft over a stop 0.2 mm
  under midspan, restitution 0.5, 0.05 s), on the same with friction on the stop (mu 0.3, 0.03 s) and on
  the shipped scene over 1 s, in ms per event;
- ``profile``: the compiled run of the stop scene under cProfile, per-event time by function (the
  functions that take the most of it, own time).

    OPENBLAS_NUM_THREADS=1 python studies/lcp_core.py [--repeat 5] [--json]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time

import numpy as np

import nsfem.lcp.builders as builders
from nsfem import load_scene
from nsfem.integrate import core
from nsfem.lcp import lemke
from nsfem.simulate import run_scene

STOP = ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]', "simulation.t_end=0.05"]
#: the stop with friction (mu 0.3, 4 generators): frictional impact LCPs of 6 unknowns at most events
STOP_FRICTION = ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5, friction=0.3}]',
                 "simulation.t_end=0.03"]


def both(fn, repeat: int) -> dict:
    """Seconds of fn on the compiled path and on the reference (best of ``repeat``, the two alternating, so
    that a change of the machine's load hits both), and their ratio."""
    fast = ref = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        fast = min(fast, time.perf_counter() - t0)
        with core.reference():
            t0 = time.perf_counter()
            fn()
            ref = min(ref, time.perf_counter() - t0)
    return {"compiled_s": fast, "reference_s": ref, "speedup": ref / fast}


def recorded_lcps(scene) -> list:
    """The (A, b, keywords) of every LCP an exact run of ``scene`` solves."""
    seen, solve = [], builders.lemke
    def record(A, b, **kw):
        seen.append((A, b, kw))
        return solve(A, b, **kw)
    builders.lemke = record
    try:
        run_scene(scene, "exact")
    finally:
        builders.lemke = solve
    return seen


def friction_lcp(rng, m: int, mu: float = 0.3):
    """A random frictional contact LCP (29)'s structure: m contacts, r = 4, Delassus of a 3m + 2 dof body."""
    n = 3 * m + 2
    G = rng.standard_normal((n, n))
    M = G @ G.T + n * np.eye(n)
    B = np.kron(np.eye(m), np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]]))
    J = np.hstack([rng.standard_normal((n, m)), rng.standard_normal((n, 2 * m)) @ B])
    D = J.T @ np.linalg.solve(M, J)
    p = 4 * m
    E = np.kron(np.eye(m), np.ones((4, 1)))
    A = np.zeros((6 * m, 6 * m))
    A[:m + p, :m + p] = 0.5 * (D + D.T)
    A[m:m + p, m + p:] = E
    A[m + p:, :m] = mu * np.eye(m)
    A[m + p:, m:m + p] = -E.T
    b = np.concatenate([-rng.uniform(0.1, 1.0, m), B.T @ rng.standard_normal(2 * m), np.zeros(m)])
    return A, b, {"groups": np.array([0] * (5 * m) + [1] * m)}


def per_event_profile(scene, events: int, top: int = 15) -> list:
    prof = cProfile.Profile()
    prof.enable()
    run_scene(scene, "exact")
    prof.disable()
    stats = pstats.Stats(prof).stats
    rows = sorted(((v[2], v[3], f"{k[0].split('nsfem/')[-1]}:{k[1]}({k[2]})") for k, v in stats.items()), reverse=True)
    return [{"function": name, "own_ms_per_event": 1e3 * own / events, "cum_ms_per_event": 1e3 * cum / events}
            for own, cum, name in rows[:top]]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    args = ap.parse_args(argv)
    if core.compiled("lcp") is None:
        raise SystemExit("the compiled event core's part 'lcp' is not built (python setup.py build_ext --inplace)")
    out = {"core": core.name(), "kernel": {}, "end_to_end": {}}
    stop = load_scene("default", STOP)
    for name, scene in (("stop", stop), ("stop_friction", load_scene("default", STOP_FRICTION))):
        lcps = recorded_lcps(scene)
        events = len(run_scene(scene, "exact")[0].events)
        sizes = {}
        for A, b, _ in lcps:
            sizes[b.size] = sizes.get(b.size, 0) + 1
        row = both(lambda: [lemke(A, b, **kw) for A, b, kw in lcps], args.repeat)
        out["kernel"][f"{name}_scene_lcps"] = {
            "count": len(lcps), "sizes": sizes, **row,
            "compiled_us_per_lcp": 1e6 * row["compiled_s"] / len(lcps),
            "reference_us_per_lcp": 1e6 * row["reference_s"] / len(lcps),
            "compiled_us_per_event": 1e6 * row["compiled_s"] / events,
            "reference_us_per_event": 1e6 * row["reference_s"] / events}
    rng = np.random.default_rng(0)
    for m in (1, 2, 3, 4):
        batch = [friction_lcp(rng, m) for _ in range(50)]
        row = both(lambda: [lemke(A, b, **kw) for A, b, kw in batch], args.repeat)
        out["kernel"][f"friction_{m}_contacts"] = {"unknowns": 6 * m, **row,
                                                   "compiled_us_per_lcp": 1e6 * row["compiled_s"] / len(batch),
                                                   "reference_us_per_lcp": 1e6 * row["reference_s"] / len(batch)}
    for name, scene in (("stop", stop), ("stop_friction", load_scene("default", STOP_FRICTION)),
                        ("shipped_1s", load_scene("default", ["simulation.t_end=1"]))):
        events = len(run_scene(scene, "exact")[0].events)
        row = both(lambda: run_scene(scene, "exact"), args.repeat)
        out["end_to_end"][name] = {"events": events, **row, "compiled_ms_per_event": 1e3 * row["compiled_s"] / events,
                                   "reference_ms_per_event": 1e3 * row["reference_s"] / events}
    out["profile_stop_compiled"] = per_event_profile(stop, out["end_to_end"]["stop"]["events"])
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for group in ("kernel", "end_to_end"):
            for name, row in out[group].items():
                print(group, name, {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()})
        for row in out["profile_stop_compiled"]:
            print(f"{row['own_ms_per_event']:8.4f} {row['cum_ms_per_event']:8.4f}  {row['function']}")
    return out


if __name__ == "__main__":
    main()
