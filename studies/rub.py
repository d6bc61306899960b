"""Rotor-stator rub of a Jeffcott rotor against speed and friction: ring force, orbits, friction work.

The shipped ``rub`` rotor (a 5 kg disk at the middle of a light 20 mm shaft, an unbalance of 1e-3 kg m,
a damper of 40 N s/m at the disk) inside a rigid ring 0.1 mm away, at speeds from 0.5 to 1.6 of its
critical speed and for several friction coefficients mu against the shaft surface (radius 10 mm,
sliding past the ring at Omega r). For each case, side by side:

- the closed form of the synchronous full annular rub, ((k - m W^2) r + N)^2 + (c W r + mu N)^2 =
  (m e W^2)^2, with the disk's mass plus 17/35 of the shaft's (no root N > 0: no synchronous rub);
- ``stationary`` (LCP 28, rotating frame, sliding friction of known direction): the ring force;
- a transient from rest (``exact`` on the same polygon, rotating frame): the contact's closed fraction and the ring force
  over the last half, the friction's dissipation and the spin's work over the run, the disk's orbit
  (inertial probes) and its whirl sense, and whether it ended in the stationary state.

Then the shipped scene itself (mu = 0.1) with ``exact``, ``moreau``, ``rk`` and ``penalty`` (each at its
default setting) side by side: wall times (issue 33's goal: no method answers faster than exact) and
what each finds over the last half (with friction the run from rest ends on a bouncing limit cycle
beside the stable sliding state; both methods find it).

Last, the round rings (``[[stator]] shape = "round"``, :mod:`nsfem.integrate.round`) side by side with the
commit before them (1b69cae, a fixed polygon), each in a subprocess on its own source tree (``git archive``
into a temporary folder), one after the other in this run: the shipped ``rub`` and ``retainer_drop`` and the
rub with beta = 1e-5 (its sliding state stable), each as that commit ships it and with the round ring
(issue 33's goal: the shipped rub and retainer_drop integrate at least 10x faster than at the baseline),
the two trees alternating over 3 rounds (the fastest run of each kept), each with the integration's wall time, its events and
events per revolution over the last half, and the ring force over the last half against ``stationary``'s.

    python studies/rub.py [--quick] [--json] [--t-end T] [--out DIR] [--no-baseline]

Writes rub.csv/.json and rub.png into studies/out/rub and copies the figure to docs/figures/rub.png.
--quick: 6 speeds, mu 0 and 0.2, t_end 1 s (about 3 minutes; the full study about 36).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

from nsfem import load_scene
from nsfem.analysis.stationary import scene_stationary
from nsfem.errors import IntegrationError, NsfemError
from nsfem.simulate import run_scene, sensor_signals

ROOT = Path(__file__).resolve().parents[1]


def jeffcott(scene) -> dict:
    """k, m (the disk plus the shaft's modal share 17/35), c, m e, the clearance r and w_n of the shipped rotor."""
    sh, disk, ring = scene["shaft"], scene["disk"][0], scene["stator"][0]
    k = 48 * sh["E"] * math.pi * sh["diameter"] ** 4 / 64 / sh["length"] ** 3
    m = disk["mass"] + 17 / 35 * sh["rho"] * math.pi * sh["diameter"] ** 2 / 4 * sh["length"]
    return {"k": k, "m": m, "c": scene["bearing"][0]["cyy"], "me": scene["unbalance"][0]["magnitude"],
            "r": ring["clearance"], "w_n": math.sqrt(k / m)}


def closed_form(j: dict, w: float, mu: float) -> float | None:
    """The ring force N of the synchronous full annular rub at the speed w [rad/s], or None (no root N > 0)."""
    a, b, f = (j["k"] - j["m"] * w * w) * j["r"], j["c"] * w * j["r"], j["me"] * w * w
    p = a + mu * b
    disc = p * p - (1 + mu * mu) * (a * a + b * b - f * f)
    if disc < 0:
        return None
    n = (-p + math.sqrt(disc)) / (1 + mu * mu)
    return n if n > 0 else None


def ring_load(forces: np.ndarray, facets: int) -> np.ndarray:
    """|sum_j N_j n_j| per column: the resultant of the facets' normal forces [N]."""
    ang = np.exp(2j * math.pi * np.arange(facets) / facets)
    return np.abs(ang @ forces)


def one_case(ratio: float, mu: float, t_end: float, j: dict) -> dict:
    speed_hz = ratio * j["w_n"] / (2 * math.pi)
    # the fixed polygon: the model LCP 28 solves (the round ring: round_vs_baseline)
    scene = load_scene("rub", [f"rotation.speed_hz={speed_hz:.9g}", f"stator.0.friction={mu:g}",
                               f"simulation.t_end={t_end:g}", "simulation.output_dt=2e-4", "stator.0.shape=polygon"])
    facets = scene["stator"][0]["facets"]
    w = 2 * math.pi * speed_hz
    n_cf = closed_form(j, w, mu)
    row = {"speed_ratio": ratio, "speed_hz": speed_hz, "mu": mu, "closed_form_N": n_cf}
    try:
        st = scene_stationary(scene)
        row["stationary_N"] = float(ring_load(st.normal_force[:, None], facets)[0])
        row["stationary_closed"] = int(np.sum(st.normal_force > 0))
    except NsfemError as exc:
        row["stationary_N"], row["stationary_closed"], row["stationary_error"] = None, None, str(exc)
        st = None
    t0 = time.perf_counter()
    try:
        res, system = run_scene(scene, "exact")
        row["error"] = ""
    except IntegrationError as exc:   # rolling on the ring (dry whip): keep what was computed
        res, system, row["error"] = exc.result, None, str(exc)
    row["wall_s"] = time.perf_counter() - t0
    row["events"] = len(res.events)
    row["impacts"] = len(res.impacts)
    late = res.t >= res.t[-1] / 2
    load = ring_load(res.normal_force, facets)
    row["closed_fraction_last_half"] = float(np.mean(np.any(res.normal_force[:, late] > 0, axis=0)))
    row["ring_force_last_half_N"] = float(load[late].mean())
    e = res.energy
    row["dissipated_friction_J"] = e["dissipated_friction_J"]
    row["work_spin_J"] = e["work_spin_J"]
    row["lost_in_impacts_J"] = e["lost_in_impacts_J"]
    row["energy_relative_residual"] = e["relative_residual"]
    row["ends_in_stationary"] = bool(st is not None and res.completed and np.allclose(
        res.normal_force[:, -1], st.normal_force, rtol=1e-3, atol=1e-3 * max(float(st.normal_force.max()), 1e-300)))
    orbit = None
    if system is not None:
        s = sensor_signals(res, system)      # disk_y, disk_z in the inertial frame
        y, z = s[late, 0], s[late, 1]
        dy, dz = np.gradient(y, res.t[late]), np.gradient(z, res.t[late])
        row["orbit_radius_max_m"] = float(np.hypot(y, z).max())
        # the whirl's sense from the orbit's swept area: + forward (with the spin), - backward
        row["whirl"] = "forward" if np.mean(y * dz - z * dy) > 0 else "backward"
        # the same orbit seen turning with the shaft: the synchronous rub is a point, a vibration about it a loop;
        # radial and circumferential offsets from its mean position, and the ring load over the last 20 ms
        rot = (y + 1j * z) * np.exp(-1j * w * res.t[late])
        centre = rot.mean()
        local = (rot - centre) * np.conj(centre) / abs(centre) if abs(centre) > 0 else rot
        last = res.t >= res.t[-1] - 0.02
        orbit = {"radial": local.real.tolist(), "circumferential": local.imag.tolist(),
                 "t": (res.t[last] - res.t[last][0]).tolist(), "load": load[last].tolist()}
    return {"row": row, "orbit": orbit}


def methods_side_by_side(t_end: float) -> list[dict]:
    """The shipped rub (mu = 0.1) from rest with exact and with moreau, in this process one after the other:
    wall time and what each says of the motion over the last half (the contact's closed fraction, the
    dominant frequency and size of the disk's vibration in the rotating frame)."""
    out = []
    for method in ("exact", "moreau", "rk", "penalty"):
        scene = load_scene("rub", [f"simulation.t_end={t_end:g}"])
        t0 = time.perf_counter()
        try:
            res, _ = run_scene(scene, method)
        except NsfemError as exc:   # a method that refuses the scene or stops gives no answer
            out.append({"method": method, "wall_s": None, "t_end": t_end, "failure": str(exc)[:300]})
            continue
        wall = time.perf_counter() - t0
        late = res.t >= res.t[-1] / 2
        q = res.q[:, late]
        x = q[int(np.argmax(q.std(axis=1)))]
        f = np.fft.rfftfreq(x.size, float(res.t[1] - res.t[0]))
        peak = float(f[1 + int(np.argmax(np.abs(np.fft.rfft(x - x.mean()))[1:]))])
        out.append({"method": method, "wall_s": wall, "t_end": t_end,
                    "closed_fraction_last_half": float(np.mean(np.any(res.normal_force[:, late] > 0, axis=0))),
                    "peak_hz": peak, "vibration_std_max": float(q.std(axis=1).max()), "impacts": len(res.impacts),
                    "energy_relative_residual": res.energy["relative_residual"],
                    "step_s": res.info.get("step_s")})
    return out


#: the commit the round rings start from (a fixed polygon)
BASELINE = "1b69cae"
#: rounds of the side-by-side runs against the baseline (the fastest run of each tree kept)
REPEAT = 3

#: run in a subprocess with PYTHONPATH on one source tree: integrate a scene, print its figures as JSON
_TIMING = r"""
import json, math, sys
import numpy as np
from nsfem import load_scene
from nsfem.simulate import run_scene
scene = load_scene(sys.argv[1], sys.argv[2:])
res, system = run_scene(scene, "exact")
F = scene["stator"][0]["facets"]
load = np.abs(np.exp(2j * math.pi * np.arange(F) / F) @ res.normal_force[:F])
T = float(res.t[-1])
late = res.t >= T / 2
out = {"wall_s": res.wall_s, "events": len(res.events), "impacts": len(res.impacts),
       "events_per_rev_last_half": sum(e["t"] >= T / 2 for e in res.events) / (scene["rotation"]["speed_hz"] * T / 2),
       "ring_N_mean_last_half": float(load[late].mean()), "ring_N_min_last_half": float(load[late].min()),
       "ring_N_max_last_half": float(load[late].max()), "energy_relative_residual": res.energy["relative_residual"],
       "round_rings": res.info.get("round_rings")}
if scene["rotation"]["frame"] == "rotating":
    from nsfem.analysis.stationary import scene_stationary
    st = scene_stationary(scene)
    out["stationary_N"] = float(abs(np.exp(2j * math.pi * np.arange(F) / F) @ st.normal_force[:F]))
print(json.dumps(out))
"""


def round_vs_baseline(quick: bool) -> list[dict]:
    """The round rings against the fixed polygon of :data:`BASELINE`, each scene on both source trees in turn
    (module docstring)."""
    rub_t = 1.0 if quick else 2.0
    # the shipped rub as each commit ships it (the goal's case: beta 1e-6 at the baseline, 1e-5 now, both
    # polygons), then with the same damping on both sides, each with the polygon and the round ring
    cases = [("rub", [f"simulation.t_end={rub_t:g}"], []),
             ("rub", [f"simulation.t_end={rub_t:g}"], ["stator.0.shape=round"]),
             ("rub", [f"simulation.t_end={rub_t:g}", "damping.rayleigh=[0.0, 1e-5]"], []),
             ("rub", [f"simulation.t_end={rub_t:g}", "damping.rayleigh=[0.0, 1e-5]"], ["stator.0.shape=round"]),
             ("retainer_drop", ["simulation.t_end=0.1"] if quick else [], [])]   # round in the scene
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", BASELINE], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", tmp], input=archive.stdout, check=True)
        for name, overrides, rounds in cases:
            row = {"scene": name, "overrides": " ".join(overrides), "this_commit_adds": " ".join(rounds)}
            # the two trees alternate, REPEAT rounds; the fastest run of each is kept (the machine is shared)
            for _ in range(REPEAT):
                for label, tree, more in (("baseline", tmp, []), ("round", str(ROOT), rounds)):
                    env = {**os.environ, "PYTHONPATH": tree, "MPLBACKEND": "Agg"}
                    run = subprocess.run([sys.executable, "-c", _TIMING, name, *overrides, *more], env=env, cwd=tree,
                                         capture_output=True, text=True)
                    if run.returncode:
                        row[f"{label}_error"] = (run.stderr.strip().splitlines() or ["?"])[-1]
                        continue
                    found = json.loads(run.stdout.strip().splitlines()[-1])
                    if found["wall_s"] < row.get(f"{label}_wall_s", math.inf):
                        row.update({f"{label}_{key}": val for key, val in found.items()})
            if "baseline_wall_s" in row and "round_wall_s" in row:
                row["speedup"] = row["baseline_wall_s"] / row["round_wall_s"]
            rows.append(row)
    return rows


def plot(path: Path, rows: list[dict], orbits: dict, j: dict, mus: list[float]) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 4, figsize=(20, 4.8))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fine = np.linspace(min(r["speed_ratio"] for r in rows), max(r["speed_ratio"] for r in rows), 400)
    for c, mu in zip(colors, mus):
        mine = [r for r in rows if r["mu"] == mu]
        cf = [closed_form(j, x * j["w_n"], mu) for x in fine]
        ax[0].plot(fine, [np.nan if v is None else v for v in cf], color=c, lw=1, label=f"closed form, mu = {mu:g}")
        ax[0].plot([r["speed_ratio"] for r in mine], [np.nan if r["stationary_N"] is None else r["stationary_N"]
                                                      for r in mine], "o", mfc="none", color=c,
                   label="stationary (LCP 28)" if mu == mus[0] else None)
        ax[0].plot([r["speed_ratio"] for r in mine], [r["ring_force_last_half_N"] for r in mine], "x", color=c,
                   label="transient, mean of the last half" if mu == mus[0] else None)
        ax[1].plot([r["speed_ratio"] for r in mine], [r["dissipated_friction_J"] for r in mine], "o-", color=c,
                   label=f"friction dissipated, mu = {mu:g}")
        ax[1].plot([r["speed_ratio"] for r in mine], [r["work_spin_J"] for r in mine], "x--", color=c,
                   label="spin's work through friction" if mu == mus[-1] else None)
    ax[0].set(xlabel="speed / critical speed", ylabel="ring force [N]", title="synchronous full annular rub")
    ax[1].set(xlabel="speed / critical speed", ylabel="work over the run [J]", title="friction")
    for c, (label, o) in zip(colors, orbits.items()):
        ax[2].plot(1e6 * np.asarray(o["circumferential"]), 1e6 * np.asarray(o["radial"]), color=c, lw=0.8, label=label)
        ax[3].plot(1e3 * np.asarray(o["t"]), o["load"], color=c, lw=0.8, label=label)
    ax[2].set(xlabel="along the ring [um]", ylabel="outwards [um]",
              title="disk orbit turning with the shaft, last half\n(about its mean position on the ring)")
    ax[3].set(xlabel="time [ms]", ylabel="ring load [N]", title="contact force, last 20 ms")
    for a in ax:
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="6 speeds, mu 0 and 0.2, t_end 1 s")
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    ap.add_argument("--t-end", type=float, help="simulated time per run [s] (default 3, --quick 1)")
    ap.add_argument("--out", default="studies/out/rub")
    ap.add_argument("--no-baseline", action="store_true", help=f"skip the round rings against {BASELINE}")
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr) if args.json else print
    out = Path(args.out)
    t_end = args.t_end or (1.0 if args.quick else 3.0)
    ratios = np.linspace(0.5, 1.6, 6 if args.quick else 12).round(4).tolist()
    mus = [0.0, 0.2] if args.quick else [0.0, 0.1, 0.3]
    j = jeffcott(load_scene("rub"))
    t0 = time.perf_counter()
    rows, orbits = [], {}
    show = {(ratios[len(ratios) // 3], mus[-1]), (ratios[len(ratios) // 3], mus[0]), (ratios[len(ratios) // 3], mus[1])}
    for mu in mus:
        for ratio in ratios:
            case = one_case(ratio, mu, t_end, j)
            r = case["row"]
            rows.append(r)
            if (ratio, mu) in show and case["orbit"] is not None:
                orbits[f"{ratio:g} w_n, mu = {mu:g}"] = case["orbit"]
            say(f"speed {ratio:.3f} w_n, mu {mu:g}: closed form "
                + ("none" if r["closed_form_N"] is None else f"{r['closed_form_N']:.3f} N")
                + ", stationary " + ("none" if r["stationary_N"] is None else f"{r['stationary_N']:.3f} N")
                + f", transient {r['ring_force_last_half_N']:.3f} N (closed {100 * r['closed_fraction_last_half']:.0f} %,"
                f" {r.get('whirl', '?')} whirl, {r['impacts']} impacts, {r['wall_s']:.2f} s)"
                + (f"; stopped: {r['error']}" if r["error"] else ""), flush=True)
    wall = time.perf_counter() - t0
    methods = methods_side_by_side(t_end)
    for mm in methods:
        if mm["wall_s"] is None:
            say(f"shipped rub, {mm['method']}: no answer ({mm['failure']})")
            continue
        say(f"shipped rub, {mm['method']}: {mm['wall_s']:.2f} s for {t_end:g} s ({mm['wall_s'] / methods[0]['wall_s']:.3g}"
            f" x exact's time); last half: closed {100 * mm['closed_fraction_last_half']:.1f} %, {mm['peak_hz']:.1f} Hz, "
            f"{mm['impacts']} impacts")
    answered = [mm for mm in methods[1:] if mm["wall_s"] is not None]
    first = min(answered, key=lambda mm: mm["wall_s"]) if answered else None
    if first is not None:
        say(f"fastest other answer: {first['method']} at {first['wall_s'] / methods[0]['wall_s']:.3g} x exact's time"
            + ("" if first["wall_s"] >= methods[0]["wall_s"] else " (FASTER THAN EXACT)"))
    rounds = [] if args.no_baseline else round_vs_baseline(args.quick)
    for r in rounds:
        say(f"{r['scene']} {r['overrides']}" + (f" (+ {r['this_commit_adds']} now)" if r["this_commit_adds"] else "")
            + f": integration {r.get('baseline_wall_s', float('nan')):.2f} s at "
            f"{BASELINE}, {r.get('round_wall_s', float('nan')):.2f} s now ({r.get('speedup', float('nan')):.2f}x, goal 10x); "
            f"events {r.get('baseline_events')} / {r.get('round_events')}, per revolution over the last half "
            f"{r.get('baseline_events_per_rev_last_half', float('nan')):.1f} / "
            f"{r.get('round_events_per_rev_last_half', float('nan')):.1f}; ring force over the last half "
            f"{r.get('baseline_ring_N_min_last_half', float('nan')):.3f}-{r.get('baseline_ring_N_max_last_half', float('nan')):.3f}"
            f" / {r.get('round_ring_N_min_last_half', float('nan')):.3f}-{r.get('round_ring_N_max_last_half', float('nan')):.3f} N"
            + (f" (stationary {r['round_stationary_N']:.4f} N)" if "round_stationary_N" in r else ""), flush=True)
    out.mkdir(parents=True, exist_ok=True)
    fig = plot(out / "rub.png", rows, orbits, j, mus)
    docs_fig = ROOT / "docs" / "figures" / "rub.png"
    if not args.quick or not docs_fig.exists():
        shutil.copyfile(fig, docs_fig)
    both = [r for r in rows if r["closed_form_N"] is not None and r["stationary_N"] is not None]
    dev = max((abs(r["stationary_N"] / r["closed_form_N"] - 1) for r in both), default=None)
    findings = {"jeffcott": j, "stationary_vs_closed_form_max_rel": dev,
                "ended_in_stationary": sum(r["ends_in_stationary"] for r in rows),
                "backward_whirl": [[r["speed_ratio"], r["mu"]] for r in rows if r.get("whirl") == "backward"],
                "stopped": [[r["speed_ratio"], r["mu"], r["error"]] for r in rows if r["error"]],
                "friction_dissipation_negative": [[r["speed_ratio"], r["mu"]] for r in rows
                                                  if r["dissipated_friction_J"] < 0]}
    payload = {"quick": args.quick, "t_end": t_end, "ratios": ratios, "mus": mus, "runs": len(rows),
               "wall_s": wall, "findings": findings, "methods": methods,
               "moreau_over_exact_wall": methods[1]["wall_s"] / methods[0]["wall_s"] if methods[1]["wall_s"] else None,
               "fastest_other": None if first is None else {"method": first["method"],
                                                            "over_exact_wall": first["wall_s"] / methods[0]["wall_s"]},
               "exact_is_fastest": first is None or first["wall_s"] >= methods[0]["wall_s"], "machine": machine(),
               "round_vs_baseline": rounds, "baseline_commit": BASELINE}
    write_outputs(out, "rub", rows, payload)
    say(f"{len(rows)} runs in {wall:.1f} s; stationary against the closed form: "
        + ("-" if dev is None else f"{dev:.2e}") + f"; {findings['ended_in_stationary']} transients ended in the "
        f"stationary state; backward whirl at {findings['backward_whirl']}")
    say(f"wrote {out}/rub.csv, .json, {fig}")
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
