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

``--touching`` (instead): where the layers touch. (1) At alpha 0.5 and ``--touch-speed`` (22.78 Hz), from the open
orbit of ``--lead-speed`` (22.74 Hz), ``--revolutions`` of transient, then :func:`smoothness` of the period map
there: its events (closings that re-open at once), the monodromy against central differences of the flow at two
steps with the perturbed flows' event counts, the number of multipliers near the unit circle. (2) With
stiffness-proportional damping ``--beta`` (alpha 0; the contact modes decay within revolutions): the open orbits over
``--open-speeds``, the transient into contact at the touch speed, the touching orbits by natural continuation in the
speed (:func:`touching_branch`, step ``--step``) and a stability check of the first (:func:`contraction`: a
perturbation along its leading Floquet direction under the exact transient). Writes delamination_touching.json/.csv
and docs/figures/delamination_touching.png.

    python studies/delamination_resonance.py --touching [--beta 1e-5] [--step 0.0025]
"""

from __future__ import annotations

import argparse
import json
import math
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
from nsfem.periodic.shooting import admissible_directions  # noqa: E402
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
              revolutions: int, beta: float = 0.0) -> tuple[dict, tuple | None]:
    """One speed's synchronous orbit from ``start`` (q, v) (None: ``lead`` revolutions from the scene's start).
    Shot when one revolution from the start is open and the shooting ends within ``budget_s`` with an open orbit;
    else the layers touch and the row summarizes a transient (:func:`touching_row`)."""
    system, T, q0, v0 = build(alpha, speed, beta)
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
           revolutions: int, beta: float = 0.0) -> list[dict]:
    """The synchronous orbits over ``speeds`` at one damping, each from the previous open orbit."""
    rows, start = [], None
    for s in speeds:
        row, nxt = orbit_row(alpha, float(s), start, lead, max_iter, budget_s, revolutions, beta)
        start = nxt if nxt is not None else start
        rows.append(row)
        print(f"alpha {alpha:g} speed {s:.4f}: converged {row['converged']} events {row['events_per_period']} "
              f"gap_min {row['gap_min_m']:.3e} m |mu| {row['largest_multiplier']} force {row['normal_force_max_N']:.3g} N", file=sys.stderr, flush=True)
    return rows


def transient(alpha: float, speed: float, start, periods: int, system=None, beta: float = 0.0,
              end: list | None = None) -> list[dict]:
    """Revolution by revolution from ``start``: the smallest gap, largest contact force and events of each (and
    the change of the state over it, relative); ``end`` (a list) receives the state (q, v) after the last."""
    if system is None:
        system = build(alpha, speed, beta)[0]
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
                    "midspan_m": midspan(system, speed, np.asarray(r.t), r.q),
                    "change": float(max(np.abs(f.q - q).max(), np.abs(f.v - v).max() * T / (2 * np.pi))
                                    / max(np.abs(q).max(), 1e-300))})
        q, v = f.q, f.v
    if end is not None:
        end.extend([q, v])
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
                    max_iter: int) -> tuple[list[dict], object]:
    """(rows, the orbit at ``start_speed``): the orbits where the layers touch, stiffness damping ``beta``
    (alpha 0), by natural continuation in the speed from the touching state ``start`` at ``start_speed``: each
    speed shot from the previous orbit, upwards then downwards by ``step`` within ``limits``, a direction ending
    at the first speed whose shooting does not converge or whose orbit has no event (the open branch)."""
    system = build(0.0, start_speed, beta)[0]
    first, o = touching_orbit(system, start_speed, start, max_iter)
    rows = [first]
    _say(beta, first)
    if not first["converged"]:
        return rows, o
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
    return sorted(rows, key=lambda r: r["speed_hz"]), o


def _say(beta: float, row: dict) -> None:
    print(f"beta {beta:g} speed {row['speed_hz']:.4f}: converged {row['converged']} (res {row['residual']:.1e}, "
          f"{row['iterations']} it) events {row['events_per_period']} force {row['normal_force_max_N']:.3g} N "
          f"midspan {row['midspan_m'] * 1e3:.3f} mm |mu| {row['largest_multiplier']:.5f}", file=sys.stderr, flush=True)


def smoothness(system, T: float, q, v, hs=(1e-6, 1e-8), count: int = 6, seed: int = 0) -> dict:
    """Is the period map smooth at (q, v)? One exact period with its monodromy, its events (closings that leave
    their point open: plastic impacts at one point that throw it or its neighbours off again), and per step h
    (relative to the state's size) the central differences of the flow along ``count`` random coordinates against
    the monodromy (relative error) and the event counts of the perturbed flows: a count that changes means the map
    is non-smooth at that scale, so Newton with the exact Jacobian cannot converge below it."""
    phi = FlowMap(system, 0.0, T)
    f = phi(q, v, jacobian=True)
    ev = f.result.events
    n, w = system.n, 2.0 * np.pi / T
    closings = [e for e in ev if "close" in e["kinds"]]
    reopened = sum(1 for e in closings if not set(e["contacts"]) <= set(e["after"]["closed"]))
    out = {"events": len(ev), "closings": len(closings), "closings_left_open": reopened,
           "releases": sum(1 for e in ev if "release" in e["kinds"]),
           "contacts_closing": sorted({c for e in closings for c in e["contacts"]}), "steps": []}
    # the spectrum of the period map on the section's admissible directions: how many directions barely contract
    Z = admissible_directions(system, f.start_mode)
    mu = np.abs(np.linalg.eigvals(Z.T @ f.monodromy @ Z))
    out["multipliers_above"] = {str(m): int(np.sum(mu > m)) for m in (0.5, 0.9, 0.98)}
    out["dimension"] = int(mu.size)
    rng = np.random.default_rng(seed)
    size = max(float(np.abs(q).max()), 1e-300)
    for h in hs:
        errs, counts = [], []
        for j in rng.choice(2 * n, count, replace=False):
            dx = np.zeros(2 * n)
            dx[j] = h * size * (1.0 if j < n else w)
            fp = phi(q + dx[:n], v + dx[n:], jacobian=False)
            fm = phi(q - dx[:n], v - dx[n:], jacobian=False)
            cd = 0.5 * (np.concatenate([fp.q, fp.v]) - np.concatenate([fm.q, fm.v]))
            pred = f.monodromy @ dx
            errs.append(float(np.linalg.norm(cd - pred) / np.linalg.norm(pred)))
            counts.append([len(fp.result.events), len(fm.result.events)])
        out["steps"].append({"h": h, "relative_error": errs, "event_counts": counts})
    return out


def contraction(system, T: float, orbit, periods: int, size: float = 1e-8) -> dict:
    """A perturbation of relative ``size`` along the orbit's leading Floquet direction, followed by the exact
    transient for ``periods`` periods: its decay per period against the leading multiplier's modulus."""
    n = system.n
    w, V = np.linalg.eig(orbit.monodromy)
    j = int(np.argmax(np.abs(w)))
    dx = orbit.directions @ np.real(V[:, j])
    dx *= size * max(float(np.abs(orbit.q0).max()), 1e-300) / np.abs(dx[:n]).max()
    phi = FlowMap(system, orbit.t0, T)
    q, v, d = orbit.q0 + dx[:n], orbit.v0 + dx[n:], []
    for _ in range(periods):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
        d.append(float(np.linalg.norm(np.concatenate([q - orbit.q0, v - orbit.v0]))))
    rate = (d[-1] / float(np.linalg.norm(dx))) ** (1.0 / periods)
    return {"periods": periods, "multiplier": complex(w[j]).real, "imag": complex(w[j]).imag, "rate": rate,
            "distances": d, "initial": float(np.linalg.norm(dx))}


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


def touching(args) -> dict:
    """The touching part (``--touching``): why the shooting fails at alpha 0.5, and the branch that converges with
    stiffness-proportional damping ``--beta`` (alpha 0) instead."""
    # 1. the diagnosis at alpha 0.5, 22.78 Hz: the transient from the open orbit at 22.74 Hz, then the period map's
    #    smoothness at its end
    a, lo, hi = 0.5, args.lead_speed, args.touch_speed
    row, start = orbit_row(a, lo, None, args.lead, args.max_iter, args.budget, 40)
    system, T = build(a, hi)[:2]
    end: list = []
    trans_a = transient(a, hi, start, args.revolutions, system=system, end=end)
    diag = smoothness(system, T, *end)
    print("diagnosis:", json.dumps({k: v for k, v in diag.items() if k != "steps"}),
          [(st["h"], np.round(st["relative_error"], 3).tolist(), st["event_counts"]) for st in diag["steps"]],
          file=sys.stderr, flush=True)
    # 2. stiffness damping: the open branch, the transient into contact at touch_speed, the touching branch
    b = args.beta
    speeds = parse_speeds(args.open_speeds)
    open_rows = branch(0.0, speeds, args.lead, args.max_iter, args.budget, 40, b)
    row, start = orbit_row(0.0, lo, None, args.lead, args.max_iter, args.budget, 40, b)
    system, T = build(0.0, hi, b)[:2]
    end = []
    trans_b = transient(0.0, hi, start, args.revolutions, system=system, beta=b, end=end)
    rows, orbit = touching_branch(b, hi, args.step, (float(speeds[0]), float(speeds[-1])), tuple(end), args.max_iter)
    contr = contraction(system, T, orbit, args.contraction_periods) if orbit.converged else None
    if contr:
        print("contraction:", contr["rate"], "multiplier", contr["multiplier"], file=sys.stderr)
    payload = {"study": "delamination_touching", "scene": "default", "beta_s": b, "touch_speed_hz": hi,
               "diagnosis_alpha_0_5": {"transient": trans_a, "smoothness": diag},
               "open_branch": open_rows, "transient": trans_b, "touching_branch": rows, "contraction": contr,
               "machine": machine()}
    write_outputs(Path(args.out), "delamination_touching", rows, payload)
    if orbit.converged:   # the orbit's section state (tests/data/delamination_touching_orbit.npz is one such)
        np.savez(Path(args.out) / "delamination_touching_orbit.npz", q0=orbit.q0, v0=orbit.v0, t0=orbit.t0,
                 speed_hz=hi, beta=b)
    touching_figure(payload, Path(args.figure).with_name("delamination_touching.png"))
    return payload


def touching_figure(payload: dict, path: Path) -> None:
    import matplotlib
    import matplotlib.ticker
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    ob = payload["open_branch"]   # (the line broken where no open orbit exists: the layers touch there)
    ax[0].plot([r["speed_hz"] for r in ob], [r["midspan_m"] * 1e3 if r["converged"] and r["events_per_period"] == 0
                                            else np.nan for r in ob], "-o", ms=3, color="C0",
               label="open orbits (no contact)")
    tb = payload["touching_branch"]
    for ok, mk, lab in ((True, "s", "touching orbits (converged, stable)"),
                        (False, "x", "touching, shooting not converged")):
        rs = [r for r in tb if r["converged"] == ok and (r["events_per_period"] > 0)]
        if rs:
            ax[0].plot([r["speed_hz"] for r in rs], [r["midspan_m"] * 1e3 for r in rs], mk, color="C3", ms=7,
                       label=lab)
            ax[1].plot([r["speed_hz"] for r in rs], [r["events_per_period"] for r in rs], mk, color="C3", ms=7)
            ax[1].plot([r["speed_hz"] for r in rs], [r["normal_force_max_N"] for r in rs], mk, color="C2", ms=7)
    ax[0].set(xlabel="speed [Hz]", ylabel="midspan z (rotating frame), half p-p [mm]",
              title=f"beta = {payload['beta_s']:g} s: resonance through contact")
    ax[1].ticklabel_format(useOffset=False)
    ax[1].xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(5))
    ax[1].set(xlabel="speed [Hz]", ylabel="events a period (red), largest contact force [N] (green)",
              title="touching orbits")
    c = payload["contraction"]
    if c:
        k = np.arange(1, c["periods"] + 1)
        ax[2].semilogy(k, np.array(c["distances"]) / c["initial"], "o", ms=4, label="transient from the orbit")
        ax[2].semilogy(k, abs(c["multiplier"]) ** k, "-", label=f"|mu_1|^k, |mu_1| = {abs(c['multiplier']):.5f}")
        ax[2].set(xlabel="period k", ylabel="distance / initial", title="stability check (leading direction)")
    for x in ax:
        x.grid(alpha=0.3)
    ax[0].legend(fontsize=8, loc="lower center")
    if c:
        ax[2].legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def parse_speeds(text: str) -> np.ndarray:
    """LOW:HIGH:N -> N speeds from LOW to HIGH [Hz]; ValueError unless 0 < LOW <= HIGH finite and N >= 1 whole."""
    parts = text.split(":")
    if len(parts) != 3:
        raise ValueError(f"{text!r} is not LOW:HIGH:N")
    lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi and n >= 1):
        raise ValueError(f"{text!r} needs finite speeds 0 < LOW <= HIGH and N >= 1")
    return np.linspace(lo, hi, n)


def check_options(ap: argparse.ArgumentParser, args) -> None:
    """Refuse a bad option in one line (``ap.error``: exit 2) before any flow."""
    positive = {"--budget": args.budget, **({"--beta": args.beta, "--step": args.step, "--lead-speed": args.lead_speed,
                                             "--touch-speed": args.touch_speed} if args.touching else {})}
    for name, value in positive.items():
        if not (math.isfinite(value) and value > 0):
            ap.error(f"{name} must be a finite number > 0, got {value!r}")
    for name, value, least in (("--lead", args.lead, 0), ("--max-iter", args.max_iter, 1),
                               ("--revolutions", args.revolutions, 1),
                               ("--contraction-periods", args.contraction_periods, 1)):
        if value < least:
            ap.error(f"{name} must be >= {least}, got {value}")
    bad = [a for a in args.alphas if not (math.isfinite(a) and a > 0)]
    if bad and not args.touching:
        ap.error(f"--alphas must be finite numbers > 0 (mass-proportional damping, 1/s), got {bad[0]!r}")
    name, text = ("--open-speeds", args.open_speeds) if args.touching else ("--speeds", args.speeds)
    try:
        parse_speeds(text)
    except ValueError as exc:
        ap.error(f"{name}: {' '.join(str(exc).split())}")


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
    ap.add_argument("--touching", action="store_true",
                    help="instead: the diagnosis at alpha 0.5 and the touching branch with stiffness damping --beta")
    ap.add_argument("--beta", type=float, default=1e-5, help="stiffness-proportional damping [s] (--touching)")
    ap.add_argument("--lead-speed", type=float, default=22.74, help="the open orbit the transients start from [Hz]")
    ap.add_argument("--touch-speed", type=float, default=22.78, help="the touching branch's start [Hz]")
    ap.add_argument("--step", type=float, default=0.0025, help="the touching branch's speed step [Hz]")
    ap.add_argument("--open-speeds", default="22.70:22.86:17", help="LOW:HIGH:N the open branch (--touching) [Hz]")
    ap.add_argument("--contraction-periods", type=int, default=12, help="the stability check's transient")
    args = ap.parse_args(argv)
    check_options(ap, args)
    if args.touching:
        return touching(args)
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
