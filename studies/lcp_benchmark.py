"""Lemke's method: run time and pivots against LCP size.

Two families, each timed side by side in one run (best of ``--repeat``):

- ``delassus``: random frictionless contact problems A = J^T K^-1 J (J: n_modes x m,
  0.6 m modes, so more contacts than modes: rank deficient) with a planted solution
  closing about half the contacts (feasible by construction);
- ``stationary``: the stationary LCP (28) of the shipped shaft with a thin upper layer at
  rest under gravity (contacts partly closed), 9 to 150 contact points, frictionless and
  with mu = 0.3 (r = 4: the LCP has 6 unknowns per contact).

Writes ``lcp_benchmark.json`` and ``lcp_benchmark.csv`` into ``--out`` (default
studies/out/lcp_benchmark) and, with ``--json``, prints the JSON object.

    python studies/lcp_benchmark.py [--quick] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

from nsfem.lcp import lemke
from nsfem.scene import load_scene


def best_of(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def delassus(m: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    n_modes = max(4, int(0.6 * m))
    J = rng.normal(size=(n_modes, m))
    K = np.diag(np.linspace(1.0, 100.0, n_modes))
    A = J.T @ np.linalg.solve(K, J)
    # a planted solution (feasible by construction): half the contacts closed
    closed = rng.random(m) < 0.5
    lam = np.where(closed, rng.random(m), 0.0)
    w = np.where(closed, 0.0, rng.random(m) * np.abs(A).max())
    return A, w - A @ lam


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer and smaller cases")
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "lcp_benchmark"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []

    sizes = [10, 25, 50, 100, 200] if args.quick else [10, 25, 50, 100, 200, 400, 800]
    for m in sizes:
        A, b = delassus(m)
        wall, res = best_of(lambda: lemke(A, b), args.repeat)
        rows.append({"family": "delassus", "contacts": m, "unknowns": m, "pivots": res.pivots,
                     "status": res.status, "residual": res.residual, "wall_s": wall,
                     "ms_per_pivot": 1e3 * wall / max(res.pivots, 1)})

    points = [9, 25, 50] if args.quick else [9, 25, 50, 100, 150]
    for cp in points:
        for mu in (0.0, 0.3):
            scene = load_scene(None, ["rotation.speed_hz=0", "delamination.0.upper_height=0.006",
                                      f"delamination.0.contact_points={cp}", f"delamination.0.friction={mu}",
                                      "mesh.elements=160", "reduction.method=craig-bampton"])
            lcp = _stationary_problem(scene)
            wall, res = best_of(lcp.solve, args.repeat)
            lamN = lcp.split(res.x)[0]
            rows.append({"family": f"stationary mu={mu}", "contacts": cp, "unknowns": lcp.size,
                         "pivots": res.pivots, "status": res.status, "residual": res.residual, "wall_s": wall,
                         "ms_per_pivot": 1e3 * wall / max(res.pivots, 1), "closed": int(np.sum(lamN > 0))})

    payload = {"machine": machine(), "cases": rows}
    d = [r for r in rows if r["family"] == "delassus" and r["pivots"] > 0]
    if len(d) >= 3:
        x, y = np.log([r["unknowns"] for r in d]), np.log([r["wall_s"] for r in d])
        payload["delassus_time_exponent"] = float(np.polyfit(x[-3:], y[-3:], 1)[0])
    write_outputs(out, "lcp_benchmark", rows, payload)
    if args.json:
        print(json.dumps(payload))
    else:
        for r in rows:
            print(f"{r['family']:20s} contacts {r['contacts']:4d}  unknowns {r['unknowns']:4d}  pivots "
                  f"{r['pivots']:4d}  {r['status']:7s}  residual {r['residual']:.1e}  {1e3 * r['wall_s']:9.2f} ms")
        print(f"wrote {out}")
    return payload


def _stationary_problem(scene):
    from nsfem.contact.set import ContactSet
    from nsfem.fem.assemble import build_model
    from nsfem.fem.rotating import rotor_operators
    from nsfem.lcp.builders import stationary_lcp
    from nsfem.linalg import factorize
    from nsfem.reduce import scene_reduction
    from nsfem.system import scene_system

    model = build_model(scene)
    red = scene_reduction(scene, model)
    system = scene_system(scene, rotor_operators(model, red.T))
    return stationary_lcp(ContactSet.from_model(model, red), factorize(system.Q), system.f0)


if __name__ == "__main__":
    main()
