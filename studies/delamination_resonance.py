"""The delaminated shaft's steady states through its gravity resonance: when do the layers touch?

The shipped ``default`` scene (the paper's shaft, section 5) rotates; in its frame each layer of the delamination
feels the centrifugal force of its own offset from the axis (upper layer up, lower layer down), which holds the
interface open by a mean gap; gravity, turning once a revolution in that frame, adds an oscillation of the gap.
The layers touch only where the gap's oscillation exceeds its mean opening, i.e. near a resonance and at small
damping. This study measures it: for each mass-proportional damping ``alpha`` (``damping.rayleigh=[alpha, 0]``,
modal damping ratio alpha / (2 omega)) it follows the synchronous orbit over the speed through the resonance by
shooting on the exact flow (each speed started from the previous orbit) and records per orbit:

- ``gap_min_m`` / ``gap_mean_m`` / ``gap_max_m``: the interface opening over the orbit (all contact points, m):
  ``gap_min_m`` > 0 means the delamination stays open all period (a smooth, linear orbit);
- ``normal_force_max_N``, ``events_per_period``, the largest multiplier's modulus, ``stable``, ``converged``;
- ``midspan_m``: half the peak-to-peak of a sensor at midspan (lower layer, z, rotating frame; added by ``--set``), m;
  ``q_half_p2p`` the same of the largest reduced coordinate.

A speed whose first revolution from the previous orbit meets contact, or whose shooting does not end with an open
orbit within ``--budget`` seconds, counts as touching: its row summarizes the last half of a transient instead
(``converged`` false; the shooting of the touching orbit at alpha 0.5, 22.78 Hz ran for more than 8 minutes).

At 22.78 Hz it lowers the damping (2, 1.75, 1.5, 1.25, 1.15) and extrapolates the open orbits' smallest gap to
zero: the damping below which the layers touch. For the smallest damping it then integrates a transient at the speed of the smallest gap (from the neighbouring
open orbit) and records per revolution the smallest gap and the events, to show what the motion does once the
layers touch.

    python studies/delamination_resonance.py [--quick] [--json] [--alphas 2 1 0.5] [--speeds 22.5:23.06:29]

``--quick``: alphas 2 and 0.5, 15 speeds, 100-revolution transients. Writes delamination_resonance.json/.csv into
studies/out/delamination_resonance and the figure docs/figures/delamination_resonance.png.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from study_io import machine, save_figure, write_outputs

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from nsfem.fem.assemble import build_model  # noqa: E402
from nsfem.fem.constraints import dense  # noqa: E402
from nsfem.sensors import read  # noqa: E402
from nsfem.integrate.problem import ContactSystem  # noqa: E402
from nsfem.periodic import periodic_orbit  # noqa: E402
from nsfem.periodic.flow import FlowMap  # noqa: E402
from nsfem.reduce import scene_reduction  # noqa: E402
from nsfem.scene.load import load_scene  # noqa: E402
from nsfem.simulate import initial_state  # noqa: E402


#: the sensor: the lower layer's z displacement at midspan, in the shaft's (rotating) frame
SENSOR = ["sensor.0.name=midspan_z", "sensor.0.x=0.5", "sensor.0.layer=lower", "sensor.0.direction=+z",
          "sensor.0.frame=rotating"]


def build(alpha: float, speed_hz: float, beta: float = 0.0):
    """The default scene at Rayleigh damping C = alpha M + beta K (alpha [1/s], beta [s]) and speed [Hz]:
    (system, period, q0, v0)."""
    scene = load_scene("default", [f"damping.rayleigh=[{alpha!r},{beta!r}]", f"rotation.speed_hz={speed_hz!r}",
                                   *SENSOR])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    q0, v0 = initial_state(scene, model, red, system)
    system.info["study_sensors"] = tuple(scene.sensors)
    return system, 1.0 / speed_hz, q0, v0


def midspan(system, speed_hz: float, t: np.ndarray, q: np.ndarray) -> float:
    """Half the peak-to-peak of the midspan sensor (lower layer, z in the rotating frame) over t [m]."""
    y = read(system.info["study_sensors"], system.info["model"], dense(system.info["reduction"].T), t, q,
             "rotating", speed_hz)[:, 0]
    return 0.5 * float(y.max() - y.min())


def settle(system, T: float, q, v, periods: int):
    """The state after ``periods`` revolutions of the exact flow."""
    phi = FlowMap(system, 0.0, T)
    for _ in range(periods):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
    return q, v


class _Budget(Exception):
    pass


def _alarm(signum, frame):
    raise _Budget()


def touching_row(alpha: float, speed: float, system, T: float, start, revolutions: int) -> dict:
    """The motion where the layers touch: ``revolutions`` of transient from ``start``, the last half summarized."""
    trans = transient(alpha, speed, start, revolutions, system=system)
    last = trans[len(trans) // 2:]
    return {"alpha_per_s": alpha, "speed_hz": speed, "converged": False, "stable": False, "loss": None,
            "events_per_period": max(t["events"] for t in last), "largest_multiplier": None,
            "gap_min_m": min(t["gap_min_m"] for t in last), "gap_mean_m": None,
            "gap_max_m": max(t["gap_max_m"] for t in last),
            "normal_force_max_N": max(t["normal_force_max_N"] for t in last),
            "q_half_p2p": max(t["q_half_p2p"] for t in last),
            "midspan_m": max(t["midspan_m"] for t in last), "grazing": 0, "iterations": 0, "wall_s": 0.0,
            "warnings": [f"layers touch: no orbit shot; transient of {revolutions} revolutions, "
                         f"{sum(t['events'] > 0 for t in last)} of its last {len(last)} with events"]}


def orbit_row(alpha: float, speed: float, start, lead: int, max_iter: int, budget_s: float,
              revolutions: int) -> tuple[dict, tuple | None]:
    """One speed's synchronous orbit from ``start`` (q, v) (None: ``lead`` revolutions from the scene's start).
    Shot when one revolution from the start is open and the shooting ends within ``budget_s`` with an open orbit;
    else the layers touch and the row summarizes a transient (:func:`touching_row`)."""
    system, T, q0, v0 = build(alpha, speed)
    q, v = start if start is not None else settle(system, T, q0, v0, lead)
    if FlowMap(system, 0.0, T)(q, v, jacobian=False).result.events:
        return touching_row(alpha, speed, system, T, (q, v), revolutions), None
    t = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, budget_s)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            o = periodic_orbit(system, T, q, v, tol=1e-9, max_iter=max_iter)
    except _Budget:
        o = None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)
    if o is None or not o.converged or o.events_per_period:
        return touching_row(alpha, speed, system, T, (q, v), revolutions), None
    r = o.result
    mu = np.abs(o.multipliers)
    row = {"alpha_per_s": alpha, "speed_hz": speed, "converged": bool(o.converged), "stable": bool(o.stable),
           "loss": o.loss, "events_per_period": int(o.events_per_period),
           "largest_multiplier": float(mu[0]) if mu.size else 0.0,
           "gap_min_m": float(r.gap.min()), "gap_mean_m": float(r.gap.mean()), "gap_max_m": float(r.gap.max()),
           "normal_force_max_N": float(r.normal_force.max()),
           "q_half_p2p": float(0.5 * (r.q.max(axis=1) - r.q.min(axis=1)).max()),
           "midspan_m": midspan(system, speed, np.asarray(r.t), r.q),
           "grazing": len(o.grazing or []), "iterations": int(o.iterations), "wall_s": time.perf_counter() - t,
           "warnings": [str(w.message).splitlines()[0] for w in caught]}
    return row, (o.q0, o.v0)


def branch(alpha: float, speeds: np.ndarray, lead: int, max_iter: int, budget_s: float,
           revolutions: int) -> list[dict]:
    """The synchronous orbits over ``speeds`` at one damping, each from the previous open orbit."""
    rows, start = [], None
    for s in speeds:
        row, nxt = orbit_row(alpha, float(s), start, lead, max_iter, budget_s, revolutions)
        start = nxt if nxt is not None else start
        rows.append(row)
        print(f"alpha {alpha:g} speed {s:.4f}: converged {row['converged']} events {row['events_per_period']} "
              f"gap_min {row['gap_min_m']:.3e} m |mu| {row['largest_multiplier']} force {row['normal_force_max_N']:.3g} N", file=sys.stderr, flush=True)
    return rows


def transient(alpha: float, speed: float, start, periods: int, system=None) -> list[dict]:
    """Revolution by revolution from ``start``: the smallest gap, largest contact force and events of each."""
    if system is None:
        system = build(alpha, speed)[0]
    T = 1.0 / speed
    phi = FlowMap(system, 0.0, T)
    q, v = start
    out = []
    for k in range(periods):
        f = phi(q, v, jacobian=False)
        r = f.result
        out.append({"revolution": k + 1, "gap_min_m": float(r.gap.min()), "gap_max_m": float(r.gap.max()),
                    "normal_force_max_N": float(r.normal_force.max()), "events": len(r.events),
                    "q_half_p2p": float(0.5 * (r.q.max(axis=1) - r.q.min(axis=1)).max()) if r.q.size else 0.0,
                    "midspan_m": midspan(system, speed, np.asarray(r.t), r.q)})
        q, v = f.q, f.v
    return out


def touching_orbit(system, speed: float, start, max_iter: int) -> tuple[dict, object]:
    """The synchronous orbit at ``speed`` shot from ``start`` (q, v) with its row: the gap, events, force,
    midspan amplitude, multipliers (the same keys as :func:`orbit_row`, plus ``residual`` and ``closings``)."""
    t = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        o = periodic_orbit(system, 1.0 / speed, *start, tol=1e-9, max_iter=max_iter, attempts=1)
    r, mu = o.result, np.abs(o.multipliers)
    ev = r.events
    row = {"speed_hz": speed, "converged": bool(o.converged), "residual": float(o.residual),
           "stable": bool(o.stable), "loss": o.loss, "events_per_period": len(ev),
           "closings": sum(1 for e in ev if "close" in e["kinds"]), "impacts": sum(1 for e in ev if e["impact"]),
           "largest_multiplier": float(mu[0]) if mu.size else 0.0,
           "gap_min_m": float(r.gap.min()), "gap_max_m": float(r.gap.max()),
           "normal_force_max_N": float(r.normal_force.max()),
           "midspan_m": midspan(system, speed, np.asarray(r.t), r.q),
           "grazing": len(o.grazing or []), "iterations": int(o.iterations), "wall_s": time.perf_counter() - t,
           "warnings": [str(w.message).splitlines()[0] for w in caught]}
    return row, o


def touching_branch(beta: float, start_speed: float, step: float, limits: tuple[float, float], start,
                    max_iter: int) -> list[dict]:
    """The orbits where the layers touch, stiffness damping ``beta`` (alpha 0), by natural continuation in the
    speed from the touching state ``start`` at ``start_speed``: each speed shot from the previous orbit, upwards
    then downwards by ``step`` within ``limits``, a direction ending at the first speed whose shooting does not
    converge or whose orbit has no event (the open branch)."""
    system = build(0.0, start_speed, beta)[0]
    first, o = touching_orbit(system, start_speed, start, max_iter)
    rows = [first]
    _say(beta, first)
    if not first["converged"]:
        return rows
    for sign in (1.0, -1.0):
        prev, s = (o.q0, o.v0), start_speed
        while True:
            s = round(s + sign * step, 9)
            if not limits[0] <= s <= limits[1]:
                break
            row, nxt = touching_orbit(build(0.0, s, beta)[0], s, prev, max_iter)
            rows.append(row)
            _say(beta, row)
            if not row["converged"] or row["events_per_period"] == 0:
                break
            prev = (nxt.q0, nxt.v0)
    return sorted(rows, key=lambda r: r["speed_hz"])


def _say(beta: float, row: dict) -> None:
    print(f"beta {beta:g} speed {row['speed_hz']:.4f}: converged {row['converged']} (res {row['residual']:.1e}, "
          f"{row['iterations']} it) events {row['events_per_period']} force {row['normal_force_max_N']:.3g} N "
          f"midspan {row['midspan_m'] * 1e3:.3f} mm |mu| {row['largest_multiplier']:.5f}", file=sys.stderr, flush=True)


def threshold(speed: float, alphas: list[float], lead: int, max_iter: int, budget_s: float) -> list[dict]:
    """The smallest gap of the orbit at ``speed`` as the damping falls (each shot from the previous open orbit),
    and where a straight line through the last two open ones crosses zero (the damping at which the layers touch)."""
    out, start = [], None
    for a in alphas:
        row, nxt = orbit_row(a, speed, start, lead, max_iter, budget_s, 40)
        out.append({"alpha_per_s": a, "open": nxt is not None, "gap_min_m": row["gap_min_m"],
                    "midspan_m": row["midspan_m"]})
        start = nxt if nxt is not None else start
    opened = [r for r in out if r["open"]]
    if len(opened) >= 2:
        (a1, g1), (a2, g2) = [(r["alpha_per_s"], r["gap_min_m"]) for r in opened[-2:]]
        out.append({"alpha_per_s": a2 - g2 * (a2 - a1) / (g2 - g1), "open": None, "gap_min_m": 0.0,
                    "midspan_m": None, "extrapolated": True})
    return out


def figure(rows: list[dict], trans: list[dict], trans_label: str, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for alpha in sorted({r["alpha_per_s"] for r in rows}, reverse=True):
        rs = [r for r in rows if r["alpha_per_s"] == alpha]
        s = np.array([r["speed_hz"] for r in rs])
        gmin = np.array([r["gap_min_m"] for r in rs]) * 1e3
        amp = np.array([r["midspan_m"] for r in rs]) * 1e3
        ok = np.array([r["converged"] and r["events_per_period"] == 0 for r in rs])
        line, = ax[0].plot(s, amp, "-", label=f"alpha = {alpha:g} 1/s")
        ax[0].plot(s[~ok], amp[~ok], "x", color=line.get_color(), ms=9)
        ax[1].plot(s, gmin, "-o", ms=3, color=line.get_color(), label=f"alpha = {alpha:g} 1/s")
        ax[1].plot(s[~ok], gmin[~ok], "x", color=line.get_color(), ms=9)
    ax[0].set(xlabel="speed [Hz]", ylabel="midspan z (rotating frame), half p-p [mm]",
              title="resonance (x: layers touch, no converged orbit)")
    ax[1].axhline(0.0, color="k", lw=0.8)
    ax[1].set(xlabel="speed [Hz]", ylabel="smallest interface gap over the orbit [mm]",
              title="open all period while > 0")
    for a in ax[:2]:
        a.legend(fontsize=8)
        a.grid(alpha=0.3)
    if trans:
        k = [t["revolution"] for t in trans]
        ax[2].plot(k, [t["gap_min_m"] * 1e3 for t in trans], "-o", ms=3, label="smallest gap [mm]")
        ax2 = ax[2].twinx()
        ax2.plot(k, [t["events"] for t in trans], "s", color="C3", ms=3, label="events")
        ax2.set_ylabel("events in the revolution", color="C3")
        ax[2].set(xlabel="revolution", ylabel="smallest gap [mm]", title=trans_label)
        ax[2].grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


def parse_speeds(text: str) -> np.ndarray:
    lo, hi, n = text.split(":")
    return np.linspace(float(lo), float(hi), int(n))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="alphas 2 and 0.5, 15 speeds, 100-revolution transients")
    ap.add_argument("--json", action="store_true", help="print the JSON payload")
    ap.add_argument("--alphas", type=float, nargs="+", default=[2.0, 1.0, 0.5], help="mass-proportional damping [1/s]")
    ap.add_argument("--speeds", default="22.5:23.06:29", help="LOW:HIGH:N speeds [Hz]")
    ap.add_argument("--lead", type=int, default=20, help="transient revolutions before the first shooting")
    ap.add_argument("--max-iter", type=int, default=8, help="Newton steps per orbit")
    ap.add_argument("--budget", type=float, default=30.0, help="seconds per shooting before the speed counts as touching")
    ap.add_argument("--revolutions", type=int, default=200, help="the transients' length (revolutions)")
    ap.add_argument("--out", default=str(ROOT / "studies" / "out" / "delamination_resonance"))
    ap.add_argument("--figure", default=str(ROOT / "docs" / "figures" / "delamination_resonance.png"))
    args = ap.parse_args(argv)
    if args.quick:
        args.alphas, args.speeds, args.revolutions = [2.0, 0.5], "22.5:23.06:15", 100
    speeds = parse_speeds(args.speeds)
    rows = []
    for alpha in args.alphas:
        rows += branch(alpha, speeds, args.lead, args.max_iter, args.budget, args.revolutions)
    # the transient: smallest damping, the speed of the smallest gap, from the nearest open orbit below it
    alpha = min(args.alphas)
    rs = [r for r in rows if r["alpha_per_s"] == alpha]
    worst = min(rs, key=lambda r: r["gap_min_m"])
    below = [r for r in rs if r["speed_hz"] < worst["speed_hz"] and r["converged"] and r["events_per_period"] == 0]
    trans, label = [], ""
    if below:
        src = below[-1]
        system, T, q0, v0 = build(alpha, src["speed_hz"])
        o = periodic_orbit(system, T, *settle(system, T, q0, v0, args.lead), tol=1e-9, max_iter=args.max_iter)
        trans = transient(alpha, worst["speed_hz"], (o.q0, o.v0), args.revolutions)
        label = (f"transient at {worst['speed_hz']:.3f} Hz, alpha {alpha:g} 1/s "
                 f"(from the orbit at {src['speed_hz']:.3f} Hz)")
    thr = threshold(22.78, [2.0, 1.75, 1.5, 1.25, 1.15], args.lead, args.max_iter, args.budget)
    print("threshold:", json.dumps(thr), file=sys.stderr)
    summary = []
    for a in args.alphas:
        rs = [r for r in rows if r["alpha_per_s"] == a]
        w = min(rs, key=lambda r: r["gap_min_m"])
        summary.append({"alpha_per_s": a, "speed_hz": w["speed_hz"], "gap_min_m": w["gap_min_m"],
                        "gap_mean_m": w["gap_mean_m"], "touching_orbits": sum(
                            1 for r in rs if not (r["converged"] and r["events_per_period"] == 0)),
                        "all_open_orbits_stable": all(r["stable"] for r in rs
                                                      if r["converged"] and r["events_per_period"] == 0)})
    payload = {"study": "delamination_resonance", "scene": "default", "speeds_hz": speeds.tolist(),
               "rows": rows, "summary": summary, "threshold_22_78_hz": thr, "transient": trans, "transient_label": label,
               "machine": machine()}
    write_outputs(Path(args.out), "delamination_resonance", rows, payload)
    figure(rows, trans, label, Path(args.figure))
    if args.json:
        print(json.dumps(payload, indent=1))
    else:
        for s in summary:
            print(json.dumps(s))
    return payload


if __name__ == "__main__":
    main()
