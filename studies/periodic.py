"""A periodic orbit by shooting against the transient that reaches it (issue 36 goal: at least 10x faster).

For each scene (the shipped ``rub``, ``crack`` and the paper's delaminated shaft ``default``, and the rub in the
inertial frame, where the synchronous rub is an orbit with 64 facet passages per revolution) both start from the
scene's initial state at t = 0:

- **transient**: the exact flow period after period (one :class:`nsfem.periodic.flow.FlowMap`: configurations kept,
  no Jacobian) until the state at the section is within ``--accuracy`` of the orbit (in (q, q' / w), relative to the
  orbit's size); the orbit itself from a tight shooting (tol 1e-12) beforehand;
- **shooting**: as ``nsfem periodic`` starts it (the stationary state, LCP 28, for a scene without periodic forcing
  in its frame: the rub in the rotating frame; else one exact run of ``--lead`` periods of transient, its
  configurations handed to the shooting), then
  :func:`nsfem.periodic.periodic_orbit` to tol = accuracy / 10; its distance to the reference orbit (carried to the
  shooting's section by a flow) is checked to be within the accuracy. With ``--section quiet`` (the default) the
  lead goes on to the phase of its last period farthest from events (:func:`nsfem.periodic.flow.quiet_phase`) and
  the shooting's section lies there; ``--section start`` shoots at the lead's end, t = 0 (mod the period), as
  ``nsfem periodic`` does. On the crack the quiet section lies inside the stretch where both contacts are closed:
  Phi - I is far better conditioned there (2.7e4 against 1e7 at t = 0) and Newton needs 4 monotone steps instead of
  5 with two wild ones (docs/performance.md).

The shooting's time includes everything after the scene's system is built: its start (the stationary state's LCP,
or the lead transient), every flow, the monodromy matrices, the grazing search and the Floquet multipliers; the
transient's every period from the scene's initial state. Both are timed side by side in one process (best of
``--repeat``, single-threaded BLAS as the integrators use); the ratio is transient / shooting. ``--clock cpu``
times the process's CPU time instead of the wall clock: everything runs on one thread, so it is the wall time an
idle core would give, and other processes on a shared machine inflate it far less. A transient that has not
reached the accuracy after ``--max-periods`` is reported as a lower bound (``>``).

    python studies/periodic.py [--quick] [--json] [--accuracy 1e-4 1e-6 1e-8] [--lead 3] [--repeat 3] [--clock cpu]
                               [--section quiet|start] [--scenes ...]

``--quick``: accuracies 1e-4 and 1e-6, one repeat, at most 400 periods. Writes periodic.json/.csv into studies/out/periodic.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from study_io import machine, write_outputs

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from nsfem.fem.assemble import build_model  # noqa: E402
from nsfem.integrate.blas import single_threaded_blas  # noqa: E402
from nsfem.integrate.event_driven import Exact  # noqa: E402
from nsfem.integrate.problem import ContactSystem  # noqa: E402
from nsfem.periodic import periodic_orbit  # noqa: E402
from nsfem.periodic.flow import FlowMap, quiet_phase  # noqa: E402
from nsfem.periodic.scene import _stationary_start  # noqa: E402
from nsfem.reduce import scene_reduction  # noqa: E402
from nsfem.scene.load import load_scene  # noqa: E402
from nsfem.simulate import initial_state  # noqa: E402

#: name -> (scene, --set overrides)
#: the clock both methods are timed with (``--clock``)
CLOCK = time.perf_counter

SCENES = {
    "rub": ("rub", []),
    "rub_inertial": ("rub", ["rotation.frame=inertial"]),
    "crack": ("crack", []),
    "delamination": ("default", []),
}


def build(scene_name: str, overrides: list[str]):
    scene = load_scene(scene_name, overrides)
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    system.info.update(model=model, reduction=red)
    q0, v0 = initial_state(scene, model, red, system)
    return scene, system, 1.0 / scene.rotation.speed_hz, q0, v0


def distance(q, v, orbit, w: float) -> float:
    """|x - x*| in (q, q' / w) over the orbit's size in the same norm; ``orbit``: (q*, q*') at the same phase."""
    qr, vr = orbit
    size = max(float(np.abs(qr).max()), float(np.abs(vr).max()) / w, 1e-300)
    return max(float(np.abs(q - qr).max()), float(np.abs(v - vr).max()) / w) / size


def at_phase(system, T: float, orbit, t: float):
    """The state (q, q') of ``orbit`` (its section t0, q0, v0) at the forcing phase t (mod T): a flow from it."""
    shift = (t - orbit.t0) % T
    if not shift:
        return orbit.q0, orbit.v0
    f = FlowMap(system, orbit.t0, shift)(orbit.q0, orbit.v0, jacobian=False)
    return f.q, f.v


def transient(system, T, q0, v0, orbit, accuracy, max_periods):
    """(CPU or wall time, periods, reached): the flow period by period in one one-BLAS-thread block, as one run
    (``nsfem run``) would be (a block per period would time threadpoolctl's library scan, ~1 ms, every period)."""
    phi = FlowMap(system, 0.0, T)
    w = 2 * math.pi / T
    q, v = q0, v0
    t = CLOCK()
    with single_threaded_blas():
        for k in range(1, max_periods + 1):
            f = phi(q, v, jacobian=False)
            q, v = f.q, f.v
            if distance(q, v, orbit, w) <= accuracy:
                return CLOCK() - t, k, True
    return CLOCK() - t, max_periods, False


def shooting(system, T, q0, v0, accuracy, lead, scene=None, section="quiet"):
    """The command's way: a scene without periodic forcing starts from its stationary state (LCP 28), any other
    from ``lead`` periods of transient; with ``section="quiet"`` the lead goes on to the phase of its last period
    farthest from events (:func:`nsfem.periodic.flow.quiet_phase`), the shooting's section. Timed in one
    one-BLAS-thread block, as the transient is."""
    t = CLOCK()
    q, v, t0 = q0, v0, 0.0
    with single_threaded_blas():
        start = _stationary_start(scene, system) if scene is not None and not system.harmonic else None
        kept = None
        if start is not None:
            q, v = start, np.zeros(system.n)
        elif lead:   # one exact run keeping its configurations for the shooting (orbit_of_scene's transient)
            kept = {}
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                res = Exact(system, progress=False, energy_balance=False, configurations=kept).run(lead * T, T, q, v)
            q, v = res.q[:, -1].copy(), res.v[:, -1].copy()
            if section == "quiet":
                t0 = quiet_phase([e["t"] for e in res.events + res.impacts if e["t"] >= (lead - 1) * T], T)
                if t0:   # (the lead's configurations: every section's, FlowMap.share)
                    to_section = FlowMap(system, 0.0, t0)
                    to_section.share(kept)
                    f = to_section(q, v, jacobian=False)
                    q, v = f.q, f.v
        orbit = periodic_orbit(system, T, q, v, t0, tol=accuracy / 10, lead=kept)
    return CLOCK() - t, orbit


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="accuracies 1e-4 and 1e-6, one repeat, at most 400 periods")
    ap.add_argument("--json", action="store_true", help="print the JSON payload")
    ap.add_argument("--accuracy", type=float, nargs="+", default=[1e-4, 1e-6, 1e-8],
                    help="relative distances to the orbit both must reach (one row per scene and accuracy)")
    ap.add_argument("--lead", type=int, default=3, help="transient periods before shooting")
    ap.add_argument("--repeat", type=int, default=3, help="timings per method (best kept)")
    ap.add_argument("--max-periods", type=int, default=3000, help="transient periods at most")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="time with the wall clock or the process's CPU time (one thread: an idle core's wall time)")
    ap.add_argument("--section", choices=("quiet", "start"), default="quiet",
                    help="the shooting's section after a lead transient: the phase of the lead's last period farthest "
                         "from events (quiet) or its end, t = 0 (start)")
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES), help="scenes to run")
    ap.add_argument("--out", default=str(ROOT / "studies" / "out" / "periodic"), help="output folder")
    args = ap.parse_args(argv)
    # every option checked before any flow (one line naming it, exit 2)
    for accuracy in args.accuracy:
        if not (math.isfinite(accuracy) and 0.0 < accuracy < 0.1):
            ap.error(f"--accuracy must lie in (0, 0.1) (the shooting's tolerance is a tenth of it), got {accuracy}")
    if args.lead < 0:
        ap.error(f"--lead must be >= 0 (transient periods before the shooting), got {args.lead}")
    if args.repeat < 1:
        ap.error(f"--repeat must be >= 1, got {args.repeat}")
    if args.max_periods < 1:
        ap.error(f"--max-periods must be >= 1, got {args.max_periods}")
    if args.quick:
        args.accuracy, args.repeat, args.max_periods = [1e-4, 1e-6], 1, 400
    global CLOCK
    CLOCK = time.process_time if args.clock == "cpu" else time.perf_counter
    rows = []
    for name in args.scenes:
        scene, system, T, q0, v0 = build(*SCENES[name])
        _, start = shooting(system, T, q0, v0, 1e-11, args.lead, scene, args.section)   # (as the command starts)
        ref = periodic_orbit(system, T, start.q0, start.v0, start.t0, tol=1e-12)   # the reference orbit
        ref0 = at_phase(system, T, ref, 0.0)   # its state at the transient's section t = 0 (mod T)
        w = 2 * math.pi / T
        for accuracy in args.accuracy:
            t_tr = min(transient(system, T, q0, v0, ref0, accuracy, args.max_periods) for _ in range(args.repeat))
            runs = [shooting(system, T, q0, v0, accuracy, args.lead, scene, args.section) for _ in range(args.repeat)]
            t_sh, orbit = min(runs, key=lambda r: r[0])
            err = distance(orbit.q0, orbit.v0, at_phase(system, T, ref, orbit.t0), w)
            row = {"scene": name, "ndof": system.n, "period_s": T, "events_per_period": orbit.events_per_period,
                   "largest_multiplier": float(abs(orbit.multipliers[0])) if orbit.multipliers.size else 0.0,
                   "stable": orbit.stable, "accuracy": accuracy,
                   "transient_s": t_tr[0], "transient_periods": t_tr[1], "transient_reached": t_tr[2],
                   "shooting_s": t_sh, "newton_steps": orbit.iterations, "section_s": orbit.t0, "shooting_error": err,
                   "shooting_ok": bool(orbit.converged and err <= accuracy),
                   "ratio": t_tr[0] / t_sh}
            rows.append(row)
            bound = "" if t_tr[2] else ">"
            print(f"{name:13s} n={system.n:3d} acc {accuracy:.0e} events/period {orbit.events_per_period:3d} |mu|max "
                  f"{row['largest_multiplier']:.4f}  transient {t_tr[0]:7.3f} s ({bound}{t_tr[1]} periods)  shooting "
                  f"{t_sh:6.3f} s ({orbit.iterations} Newton steps, error {err:.1e})  ratio {bound}{row['ratio']:.1f}x",
                  flush=True)
    payload = {"machine": machine(), "accuracies": args.accuracy, "lead_periods": args.lead, "clock": args.clock,
               "section": args.section,
               "rows": rows}
    write_outputs(Path(args.out), "periodic", rows, payload)
    if args.json:
        print(json.dumps(payload, indent=1))
    return payload


if __name__ == "__main__":
    main()
