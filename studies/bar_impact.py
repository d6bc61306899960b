"""A free steel bar hitting a rigid wall end-on: ``exact`` on unreduced meshes against the wave solution.

The textbook benchmark of impact on continua: a free bar (length L, wave speed c = sqrt(E / rho))
moving at v0 along its axis meets a rigid wall. A compression wave runs from the struck end to the
free end and back; the contact lasts exactly 2 L / c and the bar leaves at -v0, uniform and
unstrained (a perfectly elastic rebound, whatever the impact law of the contact point: the
point has no mass in the continuum). The scene is issue 17's: L = 1 m, a square section of
3.14e-4 m^2, E = 210 GPa, rho = 7800 kg/m^3, v0 = 0.1 m/s, clearance 5e-5 m, 2 ms simulated,
``reduction.method = "none"`` (Hermite beam elements: 5 dofs per node, the bending modes are in the
model but no contact direction sees them).

The contact point of the discrete bar is a node with mass, so the impact law matters there:

- restitution 0 (the continuum's law: the point stays on the wall while it is pushed) gives one
  impact and one release; the contact time and rebound converge to 2 L / c and v0 with the mesh
  (the discrete wave disperses: its front spreads over more elements the farther it runs, and some
  energy stays in axial vibration after the release);
- restitution 1 makes the end node chatter (it bounces off the wall and is pushed back by the bar
  every few microseconds): many impacts instead of a held contact; reported for comparison.

Per mesh: dofs, wall time of the whole run (model, reduction, configurations, search, outputs),
events, contact time / (2 L / c), rebound speed / v0 (the bar's mean axial velocity after the last
event: axial momentum over mass) and the energy residual of the run.

    python studies/bar_impact.py [--quick] [--json] [--out DIR]

``--quick``: 40 and 80 elements with restitution 0; the full study adds 200 elements (the issue's
case) and restitution 1 at 40 and 200. Writes bar_impact.csv/.json into studies/out/bar_impact.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

L, E, RHO, V0 = 1.0, 2.1e11, 7800.0, 0.1
SIDE = math.sqrt(3.14e-4)


def scene(elements: int, restitution: float):
    from nsfem import load_scene

    return load_scene(None, [
        f"shaft.length={L}", f"shaft.width={SIDE}", f"shaft.height={SIDE}", f"shaft.E={E}", f"shaft.rho={RHO}",
        'shaft.supports="free-free"', "delamination=[]",
        f'obstacle=[{{x={L}, normal="+x", clearance=5e-5, restitution={restitution}}}]',
        "rotation.speed_hz=0.0", "rotation.gravity=0.0", f"mesh.elements={elements}", 'reduction.method="none"',
        f"initial.velocity=[{V0}, 0.0, 0.0]", "simulation.t_end=2e-3", "simulation.output_dt=1e-6"])


def run_case(elements: int, restitution: float) -> dict:
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction
    from nsfem.simulate import run_scene, uniform_velocity

    sc = scene(elements, restitution)
    t0 = time.perf_counter()
    model = build_model(sc)
    red = scene_reduction(sc, model)
    result, system = run_scene(sc, model=model, reduction=red)
    wall = time.perf_counter() - t0
    u = uniform_velocity(model, red, system, [1.0, 0.0, 0.0])
    mean = (u @ system.M @ result.v[:, -1]) / (u @ system.M @ u)
    times = [e["t"] for e in result.events]
    contact = times[-1] - times[0] if times else float("nan")
    return {"elements": elements, "restitution": restitution, "dofs": system.n, "wall_s": wall,
            "integrate_s": result.wall_s, "events": len(times), "contact_over_2L_c": contact / (2 * L / math.sqrt(E / RHO)),
            "rebound_over_v0": -float(mean) / V0, "energy_relative_residual": float(result.energy["relative_residual"])}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="40 and 80 elements, restitution 0 (< 1 min)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "bar_impact"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = [(40, 0.0), (80, 0.0)] + ([] if args.quick else [(200, 0.0), (40, 1.0), (200, 1.0)])
    rows = []
    start = time.perf_counter()
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        for elements, e in cases:
            row = run_case(elements, e)
            rows.append(row)
            print(f"{elements:4d} elements ({row['dofs']} dofs), restitution {e:g}: {row['wall_s']:.1f} s, "
                  f"{row['events']} events, contact {row['contact_over_2L_c']:.4f} x 2L/c, rebound "
                  f"{row['rebound_over_v0']:.4f} x v0, energy residual {row['energy_relative_residual']:.1e}", flush=True)
    payload = {"mode": "quick" if args.quick else "full", "wall_s": time.perf_counter() - start, "cases": rows,
               "machine": machine()}
    write_outputs(out, "bar_impact", rows, payload)
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
