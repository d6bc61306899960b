"""The delaminated shaft's resonance curve with stable and unstable orbits: which variant of the paper's model bends it?

**The physics (estimate first).** The gravity resonance of the ``default`` shaft (paper section 5) is where its
lowest frequency in its own (rotating) frame equals the speed. With the layers open that is 22.777 Hz; with the
contact points held closed (frictionless: the layers may slide along each other) 22.85 Hz; with the layers stuck
(friction sticking at every point: the section acts bonded, the z bending equals the y bending, 47.99 Hz at rest
= pi/(2 L^2) sqrt(EI/(rho A)) for the full 20 x 20 mm section) 23.99 Hz, its half. The layers touch only where
gravity's oscillation of the interface gap exceeds the mean opening the centrifugal forces hold (docs/validation.md,
the section before): above a threshold amplitude A0 of the resonance (8.45 mm at midspan here). A hardening,
one-sided stiffness bends the resonance by about the closed shift times the describing function
(theta - sin theta cos theta) / pi, theta = arccos(A0 / A) (the share of the stiffness jump a harmonic motion of
amplitude A > A0 feels: :func:`bend_share`), and a fold pair with an unstable middle branch appears when that bend
exceeds the resonance's half-width. The open shaft's linear resonance (:func:`open_resonance`, one harmonic of the
linear open system) at beta = 1e-5 s: half-width 0.0163 Hz, linear peak A = 11.6 mm (A / A0 = 1.37, share 0.081):
frictionless 0.081 x 0.069 Hz = 0.006 Hz, below the half-width (no fold); stuck 0.081 x 1.218 Hz = 0.099 Hz, above
it (a fold, if the layers stuck). What the estimate leaves out decides: every closing is a plastic impact
(restitution 0) that removes the layers' relative normal velocity, so contact is an energy sink; the touching
orbits reach 10.2 mm where the linear peak is 11.6 mm, instead of climbing a bent backbone.

**The variants tried** (each from the paper's model: 9 Dirac contact points, CB 16, 40 elements): stiffness
damping beta 1e-5 s (the damping under which the touching orbits converge; the section before); with it friction
mu 0.3 (``delamination.0.friction``); friction 0.3 with beta 8e-6 and 6e-6 s; restitution 0.8; a deeper
delamination (``upper_height`` 0.014 m: open/closed 40.39/45.30 Hz at rest, a 12 % closed shift). The one this
study follows is **friction mu = 0.3 at beta = 1e-5 s**: closest to the paper (its contact law is Coulomb's between the
layers; its section 5 finds the interfacial friction's influence negligible, and here too mu 0.3 changes the
touching orbit at 22.78 Hz little: 10.16 against 10.20 mm), its orbits converge through the whole touching band,
and its curve has unstable orbits: next to where the open orbit grazes (22.7593-22.7594 Hz) touching orbits have a
real multiplier of -1.22 to -1.35 (period-doubling; their impacts are not grazing ones: 0.05 m/s, 5.5 N;
frictionless, the shooting stalls there); the stable touching orbits follow from 22.7615 Hz up to 22.7925 Hz and graze back to the open
branch below 22.795 Hz. No fold at the paper's gravity in any variant (docs/validation.md has what each gave).

``--fold``: the frictionless shaft at twice the gravity (``rotation.gravity=20``, beta 1e-5 s), where the estimate
predicts a fold (A / A0 = 2.8, bend 0.019 Hz above the 0.0163 Hz half-width): its touching branch by pseudo-arclength
(``nsfem periodic --continue``) bends to higher speeds; stable throughout, its leading multipliers a complex pair
(a first run stopped at 22.813 Hz, where contact 4 grazes, with a real multiplier 0.9972: not a fold; the
continuation that crosses grazings passes it and ends where the corrector fails at 22.81415 Hz): no fold found
(docs/validation.md).
Writes delamination_fold.json/.csv (and the branch's files in fold_branch/) into ``--out`` and
docs/figures/delamination_fold.png.

    python studies/delamination_variants.py --fold [--gravity 20] [--fold-range 22.72:22.84]

``--unstable``: the same shaft continued down from its open orbit at 22.83 Hz (``--unstable-range``) through the
open branch's grazing (22.819182 Hz) onto touching orbits, stable down to a second grazing (22.817900 Hz) where a
real multiplier jumps above 1 (1.47-1.63 below it); the departure from one of these unstable orbits, and where
pushes along its direction lead (a stable orbit with one brief contact less, next to it). Writes
delamination_unstable.json/.csv (the branch's files in unstable_branch/) and, after ``--fold`` into the same
``--out``, the figure with both.

    python studies/delamination_variants.py --unstable [--unstable-range 22.805:22.83] [--revolutions 150]

The study, at ``--mu`` and ``--beta``:

1. the resonance speeds of the open, closed and bonded shaft (:func:`resonance_speed`, damped modes in the rotating
   frame; bonded: Euler-Bernoulli in closed form) and the describing-function estimate of the bend
   (:func:`bend_share`);
2. the open orbits over ``--speeds`` (natural continuation from the scene's state: each speed from the previous
   open orbit; a speed whose orbit touches ends a direction);
3. the touching orbits by natural continuation from ``--start`` (a touching orbit's section state, default
   tests/data/delamination_touching_orbit.npz: the frictionless orbit at 22.78 Hz, mapped into this model's
   coordinates through the full ones and followed for ``--settle`` revolutions before its first shooting), down and
   up in steps of ``--step`` until a shooting fails or its orbit is open, each end refined by ``--fine`` steps;
4. the checks: a transient from the unstable orbit perturbed along its leading Floquet direction (its growth per
   period against |mu_1|), one from a stable touching orbit (its decay), and the motion at the unstable orbit's
   speed after ``--revolutions`` (what the orbit's loss leads to).

Writes delamination_variants.json/.csv into studies/out/delamination_variants and docs/figures/delamination_variants.png.

    python studies/delamination_variants.py [--mu 0.3] [--beta 1e-5] [--speeds 22.70:22.86:33]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from study_io import machine, save_figure, write_outputs
import delamination_resonance as dr

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from nsfem.analysis.damped import scene_damped_modes  # noqa: E402
from nsfem.fem.assemble import build_model  # noqa: E402
from nsfem.fem.constraints import dense  # noqa: E402
from nsfem.integrate.problem import ContactSystem  # noqa: E402
from nsfem.periodic import periodic_orbit  # noqa: E402
from nsfem.periodic.flow import FlowMap  # noqa: E402
from nsfem.reduce import scene_reduction  # noqa: E402
from nsfem.scene.load import load_scene  # noqa: E402
from nsfem.simulate import initial_state  # noqa: E402

START = ROOT / "tests" / "data" / "delamination_touching_orbit.npz"


def overrides(speed_hz: float, beta: float, mu: float, gravity: float = 9.81) -> list[str]:
    """The ``--set`` list of the variant: stiffness damping ``beta`` [s], friction ``mu``, ``gravity`` [m/s^2], the
    midspan sensor."""
    return [f"damping.rayleigh=[0.0,{beta!r}]", f"rotation.speed_hz={speed_hz!r}",
            f"delamination.0.friction={mu!r}", f"rotation.gravity={gravity!r}", *dr.SENSOR]


def build(speed_hz: float, beta: float, mu: float, gravity: float = 9.81):
    """(system, period, q0, v0) of the variant at ``speed_hz``."""
    scene = load_scene("default", overrides(speed_hz, beta, mu, gravity))
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    q0, v0 = initial_state(scene, model, red, system)
    system.info["study_sensors"] = tuple(scene.sensors)
    return system, 1.0 / speed_hz, q0, v0


def rotating_frequency(speed_hz: float, contact: str) -> float:
    """The lowest forward frequency [Hz] of the undamped default shaft in its own frame at ``speed_hz``."""
    scene = load_scene("default", [f"rotation.speed_hz={speed_hz!r}"])
    model = build_model(scene)
    modes = scene_damped_modes(scene, model, speed_hz, 2, scene_reduction(scene.reduction, model), contact)
    f = [float(x) for x, w in zip(modes.frequencies_hz, modes.whirl) if w == "forward"]
    return f[0]


def resonance_speed(contact: str, guess: float = 22.8, tol: float = 1e-6) -> float:
    """The speed [Hz] at which the rotating-frame frequency equals the speed (gravity turns once a revolution in
    that frame), by the secant method on f(speed) - speed."""
    a, b = guess, guess + 0.1
    fa, fb = rotating_frequency(a, contact) - a, rotating_frequency(b, contact) - b
    for _ in range(20):
        c = b - fb * (b - a) / (fb - fa)
        a, fa, b = b, fb, c
        fb = rotating_frequency(b, contact) - b
        if abs(b - a) < tol:
            break
    return b


def bonded_speed() -> float:
    """The bonded (stuck) shaft's gravity resonance [Hz]: half its pinned-pinned first bending frequency
    pi / (2 L^2) sqrt(EI / (rho A)) (a square section bends alike in y and z; its rotating-frame frequency is that
    minus the speed)."""
    scene = load_scene("default", [])
    s = scene["shaft"]
    EI, rhoA = s["E"] * s["width"] * s["height"] ** 3 / 12.0, s["rho"] * s["width"] * s["height"]
    return 0.5 * math.pi / (2.0 * s["length"] ** 2) * math.sqrt(EI / rhoA)


def bend_share(a: np.ndarray) -> np.ndarray:
    """The share of a one-sided stiffness jump that a harmonic motion of amplitude ``a`` (in units of the
    threshold A0 at which the stiffness engages) feels in its first harmonic (describing function):
    (theta - sin theta cos theta) / pi with theta = arccos(1 / a); 0 for a <= 1, tending to 1/2."""
    a = np.asarray(a, dtype=float)
    theta = np.arccos(np.clip(1.0 / np.maximum(a, 1.0), -1.0, 1.0))
    return (theta - np.sin(theta) * np.cos(theta)) / math.pi


def open_amplitude(speed_hz: float, beta: float, mu: float = 0.0, gravity: float = 9.81) -> float:
    """The midspan amplitude [m] (half p-p, rotating frame) of the open (linear, contact ignored) orbit at
    ``speed_hz``: M q'' + C q' + Q q = f0 + fc cos(w t) + fs sin(w t) solved by its one harmonic,
    (Q - w^2 M + i w C) X = fc - i fs, plus the static Q q_s = f0. Where the layers stay open this is the exact
    flow's orbit; where they would touch, the linear resonance the estimate needs."""
    speed_hz = float(speed_hz)
    system, T = build(speed_hz, beta, mu, gravity)[:2]
    w = 2.0 * math.pi * speed_hz
    X = np.linalg.solve(system.Q - w**2 * system.M + 1j * w * system.C, system.fc - 1j * system.fs)
    qs = np.linalg.solve(system.Q, system.f0)
    t = np.linspace(0.0, T, 513)
    q = qs[:, None] + np.real(X[:, None] * np.exp(1j * w * t)[None, :])
    return dr.midspan(system, speed_hz, t, q)


def open_resonance(beta: float, mu: float = 0.0, gravity: float = 9.81, guess: float = 22.7765) -> dict:
    """The open shaft's linear resonance from :func:`open_amplitude`: its peak speed and amplitude and its half-width
    (the -3 dB distances below and above the peak, averaged) [Hz, m]."""
    from scipy.optimize import brentq, minimize_scalar

    r = minimize_scalar(lambda sp: -open_amplitude(sp, beta, mu, gravity), bracket=(guess - 0.01, guess, guess + 0.01),
                        tol=1e-9)
    f_r, peak = float(r.x), -float(r.fun)
    level = lambda sp: open_amplitude(sp, beta, mu, gravity) - peak / math.sqrt(2.0)   # noqa: E731
    lo, hi = brentq(level, f_r - 0.1, f_r), brentq(level, f_r, f_r + 0.1)
    return {"peak_hz": f_r, "peak_m": peak, "half_width_hz": 0.5 * (hi - lo)}


def row_of(o, system, speed: float, mu: float, beta: float, wall: float, branch: str) -> dict:
    r = o.result
    mus = np.abs(o.multipliers)
    return {"branch": branch, "speed_hz": speed, "mu": mu, "beta_s": beta, "converged": bool(o.converged),
            "residual": float(o.residual), "iterations": int(o.iterations), "stable": bool(o.stable), "loss": o.loss,
            "events_per_period": int(o.events_per_period),
            "largest_multiplier": float(mus[0]) if mus.size else 0.0,
            "leading_multiplier_re": float(o.multipliers[0].real) if mus.size else 0.0,
            "leading_multiplier_im": float(o.multipliers[0].imag) if mus.size else 0.0,
            "gap_min_m": float(r.gap.min()), "normal_force_max_N": float(r.normal_force.max()),
            "midspan_m": dr.midspan(system, speed, np.asarray(r.t), r.q), "grazing": len(o.grazing or []),
            "wall_s": wall}


def shoot(speed: float, mu: float, beta: float, start, branch: str, max_iter: int):
    """(row, orbit) at ``speed`` shot from ``start`` (q, v, t0)."""
    system, T = build(speed, beta, mu)[:2]
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (near-grazing passages are counted in the row)
        o = periodic_orbit(system, T, start[0], start[1], start[2], tol=1e-9, max_iter=max_iter, attempts=1)
    row = row_of(o, system, speed, mu, beta, time.perf_counter() - t, branch)
    say(row)
    return row, o


def say(row: dict) -> None:
    print(f"{row['branch']:9s} {row['speed_hz']:.5f} Hz: converged {row['converged']} ({row['residual']:.1e}, "
          f"{row['iterations']} it) events {row['events_per_period']} midspan {row['midspan_m'] * 1e3:.3f} mm "
          f"force {row['normal_force_max_N']:.3g} N |mu_1| {row['largest_multiplier']:.5f} {row['loss'] or ''}",
          file=sys.stderr, flush=True)


def walk(speeds, mu: float, beta: float, start, branch: str, max_iter: int, touching: bool) -> list[tuple]:
    """Natural continuation over ``speeds`` from ``start`` (q, v, t0): each speed from the previous orbit; stops at
    the first shooting that fails or whose orbit leaves the branch (an open branch's orbit with events, a touching
    branch's without). Returns [(row, orbit)], the failing one last."""
    out = []
    for s in speeds:
        row, o = shoot(float(s), mu, beta, start, branch, max_iter)
        out.append((row, o))
        if not o.converged or (o.events_per_period > 0) != touching:
            break
        start = (o.q0, o.v0, o.t0)
    return out


def mapped_start(path: Path, speed: float, mu: float, beta: float, revolutions: int):
    """A touching start for the variant: the stored orbit's section state (another variant's coordinates) mapped
    through the full coordinates (least squares), then ``revolutions`` of the variant's exact flow."""
    d = np.load(path)
    s0, b0 = float(d["speed_hz"]), float(d["beta"])
    mu0 = float(d["mu"]) if "mu" in d else 0.0
    src = build(s0, b0, mu0)[0]
    system, T = build(speed, beta, mu)[:2]
    T0, T1 = dense(src.info["reduction"].T), dense(system.info["reduction"].T)
    q = np.linalg.lstsq(T1, T0 @ d["q0"], rcond=None)[0]
    v = np.linalg.lstsq(T1, T0 @ d["v0"], rcond=None)[0]
    phi = FlowMap(system, float(d["t0"]), T)
    for _ in range(revolutions):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
    return q, v, float(d["t0"])


def departure(system, T: float, o, periods: int, size: float) -> dict:
    """A perturbation of relative ``size`` along the orbit's leading Floquet direction under the exact transient:
    its distance each period (relative to the start) against |mu_1|^k, and the sign of its projection."""
    n = system.n
    w, V = np.linalg.eig(o.monodromy)
    j = int(np.argmax(np.abs(w)))
    dx = o.directions @ np.real(V[:, j])
    dx *= size * max(float(np.abs(o.q0).max()), 1e-300) / np.abs(dx[:n]).max()
    phi = FlowMap(system, o.t0, T)
    q, v = o.q0 + dx[:n], o.v0 + dx[n:]
    dist, sign = [], []
    for _ in range(periods):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
        d = np.concatenate([q - o.q0, v - o.v0])
        dist.append(float(np.linalg.norm(d) / np.linalg.norm(dx)))
        sign.append(int(np.sign(d @ dx)))
    return {"multiplier_re": float(w[j].real), "multiplier_im": float(w[j].imag), "periods": periods, "size": size,
            "relative_distance": dist, "sign": sign, "rate": dist[-1] ** (1.0 / periods)}


def _revolutions(system, T: float, t0: float, q, v, revolutions: int):
    """The exact motion from (q, q') at the section t0, revolution by revolution: ([{"revolution", "events",
    "gap_min_m", "midspan_m"}], the end state q, q')."""
    phi = FlowMap(system, t0, T)
    out = []
    for k in range(revolutions):
        f = phi(q, v, jacobian=False)
        r = f.result
        out.append({"revolution": k + 1, "events": len(r.events), "gap_min_m": float(r.gap.min()),
                    "midspan_m": dr.midspan(system, 1.0 / T, np.asarray(r.t), r.q)})
        q, v = f.q, f.v
    return out, q, v


def aftermath(system, T: float, o, revolutions: int, size: float = 1e-4) -> list[dict]:
    """The motion from the orbit's state scaled by 1 + ``size``, revolution by revolution (events, midspan)."""
    return _revolutions(system, T, o.t0, o.q0 * (1.0 + size), o.v0.copy(), revolutions)[0]


def study(args) -> dict:
    mu, beta = args.mu, args.beta
    # 1. the estimate
    f_open, f_closed, f_bonded = resonance_speed("open"), resonance_speed("closed"), bonded_speed()
    print(f"resonance speeds: open {f_open:.4f}, closed {f_closed:.4f}, bonded {f_bonded:.4f} Hz", file=sys.stderr)
    # 2. the open orbits, from the scene's own state below and above the resonance
    speeds = dr.parse_speeds(args.speeds)
    system, T, q0, v0 = build(float(speeds[0]), beta, mu)
    q, v = dr.settle(system, T, q0, v0, args.lead)
    open_lo = walk(speeds, mu, beta, (q, v, 0.0), "open", args.max_iter, touching=False)
    system, T, q0, v0 = build(float(speeds[-1]), beta, mu)
    q, v = dr.settle(system, T, q0, v0, args.lead)
    open_hi = walk(speeds[::-1], mu, beta, (q, v, 0.0), "open", args.max_iter, touching=False)
    # 3. the touching orbits from the mapped start, down and up, each end refined
    start = mapped_start(Path(args.start), args.touch_speed, mu, beta, args.settle)
    first, o = shoot(args.touch_speed, mu, beta, start, "touching", args.max_iter)
    touch = [(first, o)]
    if o.converged:
        for sign in (-1.0, 1.0):
            coarse = [round(args.touch_speed + sign * k * args.step, 9) for k in range(1, 40)]
            seq = walk(coarse, mu, beta, (o.q0, o.v0, o.t0), "touching", args.max_iter, touching=True)
            touch += seq
            good = [x for x in seq if x[0]["converged"] and x[0]["events_per_period"] > 0]
            base = good[-1] if good else (first, o)
            fine = [round(base[0]["speed_hz"] + sign * k * args.fine, 9)
                    for k in range(1, int(round(args.step / args.fine)))]
            touch += walk(fine, mu, beta, (base[1].q0, base[1].v0, base[1].t0), "touching", args.max_iter, True)
    # the unstable touching orbits: every converged one outside the circle, and their neighbours by fine steps
    unstable = [x for x in touch if x[0]["converged"] and x[0]["events_per_period"] > 0 and not x[0]["stable"]]
    extra = []
    for row, orb in unstable[:1]:
        for sign in (-1.0, 1.0):
            fine = [round(row["speed_hz"] + sign * k * args.fine, 9) for k in range(1, 8)]
            extra += walk(fine, mu, beta, (orb.q0, orb.v0, orb.t0), "unstable", args.max_iter, True)
    rows = [r for r, _ in open_lo + open_hi + touch + extra]
    # 4. the checks
    checks = {}
    if unstable:
        row, orb = unstable[0]
        system, T = build(row["speed_hz"], beta, mu)[:2]
        checks["unstable_departure"] = dict(departure(system, T, orb, args.periods, 1e-9), speed_hz=row["speed_hz"])
        checks["unstable_aftermath"] = {"speed_hz": row["speed_hz"],
                                        "revolutions": aftermath(system, T, orb, args.revolutions)}
    stable = [x for x in touch if x[0]["converged"] and x[0]["events_per_period"] > 0 and x[0]["stable"]]
    if stable:
        row, orb = min(stable, key=lambda x: abs(x[0]["speed_hz"] - args.touch_speed))
        system, T = build(row["speed_hz"], beta, mu)[:2]
        checks["stable_contraction"] = dict(departure(system, T, orb, args.periods, 1e-8), speed_hz=row["speed_hz"])
    # the half-width and linear peak of the open shaft's resonance, by harmonic balance (exact for the linear open
    # system; a single-mode fit through two flank points, used before, took 0.013 Hz and 13.4 mm for 0.0163 Hz and
    # 11.6 mm: the flank carries the other modes' background)
    lin = open_resonance(beta, mu)
    estimate = {"open_hz": f_open, "closed_hz": f_closed, "bonded_hz": f_bonded,
                "half_width_hz": lin["half_width_hz"], "linear_peak_m": lin["peak_m"], "linear_peak_hz": lin["peak_hz"]}
    payload = {"study": "delamination_variants", "scene": "default", "mu": mu, "beta_s": beta,
               "estimate": estimate, "rows": rows, "checks": checks, "machine": machine()}
    write_outputs(Path(args.out), "delamination_variants", rows, payload)
    figure(payload, Path(args.figure))
    return payload


def fold_start(args, out: Path) -> Path:
    """The touching orbit at ``--fold-start-speed`` with gravity ``--gravity`` (frictionless, ``--beta``): from the
    stored orbit (1 g, 22.78 Hz), ``--settle`` revolutions at the gravity, shot at 22.78 Hz and followed by natural
    continuation in steps of ``--step``; saved as an orbit file (q0, v0, t0) for ``nsfem periodic --start``."""
    g, beta = args.gravity, args.beta
    d = np.load(args.start)
    q, v, t0 = d["q0"], d["v0"], float(d["t0"])
    s = float(d["speed_hz"])
    system, T = build(s, beta, 0.0, g)[:2]
    phi = FlowMap(system, t0, T)
    for _ in range(args.settle):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
    speeds = np.arange(s, args.fold_start_speed + 0.5 * args.step, args.step)
    for sp in speeds:
        system, T = build(float(sp), beta, 0.0, g)[:2]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            o = periodic_orbit(system, T, q, v, t0, tol=1e-10, max_iter=args.max_iter, attempts=1)
        print(f"fold start {sp:.4f} Hz: converged {o.converged} ({o.residual:.1e}) events {o.events_per_period}",
              file=sys.stderr, flush=True)
        if not o.converged:
            raise SystemExit(f"delamination_variants: error: no touching orbit at {sp:.4f} Hz with gravity {g:g}")
        q, v, t0 = o.q0, o.v0, o.t0
    path = out / "fold_start.npz"
    np.savez(path, q0=q, v0=v, t0=t0, speed_hz=float(speeds[-1]), beta=beta, mu=0.0, gravity=g)
    return path


def continued(beta: float, g: float, speed: float, lo: float, hi: float, steps: int, out: Path,
              start: Path | None = None, step: float = 0.001) -> tuple[dict, list[dict]]:
    """The frictionless branch at gravity ``g`` by ``nsfem periodic --continue rotation.speed_hz=lo:hi`` from the
    orbit at ``speed`` (shot from ``start``, an orbit file, or after the command's transient) into ``out``:
    (branch.json's content, a row per point with its midspan amplitude from one period of the exact flow)."""
    import subprocess

    cmd = [sys.executable, "-m", "nsfem", "periodic", "default", "--set", f"damping.rayleigh=[0.0,{beta!r}]",
           "--set", f"rotation.gravity={g!r}", "--set", f"rotation.speed_hz={speed!r}",
           "--set", "output.vtu_every=0", *(["--start", str(start)] if start is not None else []),
           "--continue", f"rotation.speed_hz={lo!r}:{hi!r}", "--steps", str(steps), "--step", repr(step),
           "--out", str(out)]
    done = subprocess.run(cmd, cwd=str(ROOT), capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"delamination_variants: error: nsfem periodic --continue failed: "
                         f"{done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}")
    meta = json.loads((out / "branch.json").read_text())
    b = np.load(out / "branch.npz")
    points = []
    for i, p in enumerate(meta["branch"]):
        system, T = build(float(p["value"]), beta, 0.0, g)[:2]
        f = FlowMap(system, float(b["t0_s"][i]), T)(b["q0"][i], b["v0"][i], jacobian=False)
        mu = np.array([complex(*m) for m in p["multipliers"]])
        points.append({"speed_hz": float(p["value"]), "stable": bool(p["stable"]), "converged": bool(p["converged"]),
                       "events_per_period": int(p["events_per_period"]), "residual": float(p["residual"]),
                       "largest_multiplier": float(np.abs(mu).max()),
                       "leading_real": bool(abs(mu[0].imag) <= 1e-9), "leading_re": float(mu[0].real),
                       "midspan_m": dr.midspan(system, float(p["value"]), np.asarray(f.result.t), f.result.q)})
    return meta, points


def fold(args) -> dict:
    """``--fold``: the touching branch with gravity ``--gravity`` by pseudo-arclength (``nsfem periodic --continue``
    over ``--fold-range`` from the orbit of :func:`fold_start`), each point's midspan amplitude from one period of
    the exact flow, the open orbits over ``--speeds`` at that gravity, and the figure delamination_fold.png (with
    the branch of ``--unstable`` when its delamination_unstable.json is in ``--out``)."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = fold_start(args, out)
    g, beta = args.gravity, args.beta
    lo, hi = (float(x) for x in args.fold_range.split(":"))
    t = time.perf_counter()
    meta, points = continued(beta, g, args.fold_start_speed, lo, hi, args.fold_steps, out / "fold_branch", start)
    wall = time.perf_counter() - t
    # the open orbits at this gravity (linear where they do not touch), from the scene's state at each end
    speeds = dr.parse_speeds(args.speeds)
    opened = []
    for seq in (speeds, speeds[::-1]):
        system, T, q0, v0 = build(float(seq[0]), beta, 0.0, g)
        q, v = dr.settle(system, T, q0, v0, args.lead)
        for sp in seq:
            system, T = build(float(sp), beta, 0.0, g)[:2]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                o = periodic_orbit(system, T, q, v, 0.0, tol=1e-9, max_iter=args.max_iter, attempts=1)
            if not o.converged or o.events_per_period:
                break
            opened.append({"speed_hz": float(sp), "midspan_m": dr.midspan(system, float(sp), np.asarray(o.result.t),
                                                                          o.result.q),
                           "gap_min_m": float(o.result.gap.min()), "largest_multiplier": float(np.abs(o.multipliers[0]))})
            q, v = o.q0, o.v0
    payload = {"study": "delamination_fold", "gravity": g, "beta_s": beta, "branch": points,
               "stop": meta["stop"], "reason": meta["reason"], "sides": meta["sides"], "open": opened,
               "continuation_wall_s": wall, "machine": machine()}
    write_outputs(out, "delamination_fold", points, payload)
    side = out / "delamination_unstable.json"
    fold_figure(payload, Path(args.figure).with_name("delamination_fold.png"),
                json.loads(side.read_text()) if side.is_file() else None)
    return payload


def leave(system, T: float, o, revolutions: int, size: float) -> dict:
    """The motion from the orbit pushed along its leading Floquet direction by ``size`` (relative to its largest
    coordinate; the sign picks the side), revolution by revolution (events, smallest gap, midspan amplitude), and
    the period-1 orbit the shooting finds from where it ends (``ends_on``)."""
    n = system.n
    w, V = np.linalg.eig(o.monodromy)
    dx = o.directions @ np.real(V[:, int(np.argmax(np.abs(w)))])
    dx *= size * float(np.abs(o.q0).max()) / np.abs(dx[:n]).max()
    out, q, v = _revolutions(system, T, o.t0, o.q0 + dx[:n], o.v0 + dx[n:], revolutions)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = periodic_orbit(system, T, q, v, o.t0, tol=1e-10, max_iter=15, attempts=1)
    ends_on = {"converged": bool(e.converged), "residual": float(e.residual), "stable": bool(e.stable),
               "events_per_period": int(e.events_per_period), "largest_multiplier": float(np.abs(e.multipliers[0])),
               "midspan_m": dr.midspan(system, 1.0 / T, np.asarray(e.result.t), e.result.q),
               "distance": float(np.abs(e.q0 - o.q0).max() / np.abs(o.q0).max())}
    return {"revolutions": out, "ends_on": ends_on}


def unstable(args) -> dict:
    """``--unstable``: the branch at ``--gravity`` continued from the open orbit at the top of ``--unstable-range``
    downwards (``nsfem periodic --continue``, which crosses grazings): the open orbits, their grazing, the touching
    orbits past it and where they lose stability; at the middle unstable point the checks (a perturbation along the
    leading Floquet direction against |mu_1|^k; where pushes of +-1e-6 along it lead after ``--revolutions``, and the
    orbit the shooting finds from there).
    Writes delamination_unstable.json/.csv (and the branch's files in unstable_branch/) into ``--out``, the figure
    delamination_unstable.png and delamination_fold.png (with the branch of ``--fold`` when its
    delamination_fold.json is in ``--out``)."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    g, beta = args.gravity, args.beta
    lo, hi = (float(x) for x in args.unstable_range.split(":"))
    t = time.perf_counter()
    meta, points = continued(beta, g, hi, lo, hi, args.fold_steps, out / "unstable_branch")
    wall = time.perf_counter() - t
    grazings = [{"value": float(b["value"]), "events_per_period": b.get("events_per_period")}
                for b in meta["bifurcations"] if b["kind"] == "grazing"]
    un = sorted((i for i, p in enumerate(points) if not p["stable"] and p["events_per_period"] > 0),
                key=lambda i: points[i]["speed_hz"])
    checks = {}
    if un:
        i = un[len(un) // 2]
        b = np.load(out / "unstable_branch" / "branch.npz")
        sp = points[i]["speed_hz"]
        system, T = build(sp, beta, 0.0, g)[:2]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # (near-grazing passages: the branch's json has them)
            o = periodic_orbit(system, T, b["q0"][i], b["v0"][i], float(b["t0_s"][i]), tol=1e-12, max_iter=4,
                               attempts=1)
        checks["unstable_departure"] = dict(departure(system, T, o, args.periods, 1e-9), speed_hz=sp,
                                            residual=float(o.residual), events_per_period=int(o.events_per_period))
        checks["unstable_aftermath"] = {"speed_hz": sp, "size": 1e-6,
                                        "plus": leave(system, T, o, args.revolutions, 1e-6),
                                        "minus": leave(system, T, o, args.revolutions, -1e-6)}
        for side in ("plus", "minus"):
            pushed = checks["unstable_aftermath"][side]
            last, e = pushed["revolutions"][-1], pushed["ends_on"]
            print(f"from the unstable orbit at {sp:.6f} Hz pushed {side}: after {last['revolution']} revolutions "
                  f"{last['events']} events, midspan {last['midspan_m'] * 1e3:.5f} mm; shot from there: converged "
                  f"{e['converged']}, stable {e['stable']}, {e['events_per_period']} events, midspan "
                  f"{e['midspan_m'] * 1e3:.5f} mm, |mu_1| {e['largest_multiplier']:.4f}, {e['distance']:.1e} from the "
                  f"unstable orbit", file=sys.stderr, flush=True)
    payload = {"study": "delamination_unstable", "gravity": g, "beta_s": beta, "branch": points,
               "grazings": grazings, "stop": meta["stop"], "reason": meta["reason"], "sides": meta["sides"],
               "checks": checks, "continuation_wall_s": wall, "machine": machine()}
    write_outputs(out, "delamination_unstable", points, payload)
    side_figure(payload, Path(args.figure).with_name("delamination_unstable.png"))
    fold_json = out / "delamination_fold.json"
    if fold_json.is_file():
        fold_figure(json.loads(fold_json.read_text()), Path(args.figure).with_name("delamination_fold.png"), payload)
    else:
        print(f"delamination_variants: no {fold_json} (run --fold first): delamination_fold.png is not redrawn",
              file=sys.stderr)
    return payload


def fold_figure(payload: dict, path: Path, side: dict | None = None) -> None:
    """delamination_fold.png: the 2 g resonance curve (open orbits, the touching branch up to its fold) and its
    multipliers; with ``side`` (the payload of ``--unstable``) also the branch from the open side through its
    grazing (unstable dashed) in a zoom on the fold, and the departure from one of its unstable orbits."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = sorted(payload["branch"], key=lambda r: r["speed_hz"])
    op = sorted(payload["open"], key=lambda r: r["speed_hz"])
    fig, axes = plt.subplots(2 if side else 1, 2, figsize=(12, 8.8 if side else 4.4), squeeze=False)
    ax = axes[0]
    s = np.array([r["speed_hz"] for r in op])
    cut = np.flatnonzero(np.diff(s) > 0.006) + 1
    for k, (ps, pa) in enumerate(zip(np.split(s, cut), np.split(np.array([r["midspan_m"] for r in op]) * 1e3, cut))):
        ax[0].plot(ps, pa, "-o", ms=2.5, color="C0", label="open orbits (stable)" if k == 0 else None)
    st = [r for r in pts if r["stable"]]
    ax[0].plot([r["speed_hz"] for r in st], [r["midspan_m"] * 1e3 for r in st], "-", color="C3", lw=1.2)
    for touching, mk, lab in ((True, "s", "touching orbits, pseudo-arclength (stable)"),
                              (False, "o", "open orbits the branch reaches (stable)")):
        sel = [r for r in st if (r["events_per_period"] > 0) == touching]
        if sel:
            ax[0].plot([r["speed_hz"] for r in sel], [r["midspan_m"] * 1e3 for r in sel], mk, ms=3,
                       color="C3" if touching else "C0", mec="C3", label=lab)
    un = [r for r in pts if not r["stable"]]
    if un:
        ax[0].plot([r["speed_hz"] for r in un], [r["midspan_m"] * 1e3 for r in un], "--D", mfc="none", color="k",
                   label="touching orbits (unstable)")
    end = max(pts, key=lambda r: r["speed_hz"])
    # (what ends the branch is read from the orbits, not assumed: at 2 g a grazing of contact 4 comes before the
    # smooth piece's saddle-node; docs/validation.md)
    ax[0].plot([end["speed_hz"]], [end["midspan_m"] * 1e3], "*", ms=14, color="k",
               label=f"the branch's end ({end['speed_hz']:.6f} Hz, |mu_1| {end['largest_multiplier']:.4f}; "
                     f"continuation: {payload['stop']})")
    ax[0].set(xlabel="speed [Hz]", ylabel="midspan z (rotating frame), half p-p [mm]",
              title=f"gravity {payload['gravity']:g} m/s^2, beta {payload['beta_s']:g} s, frictionless")
    ax[1].plot([r["speed_hz"] for r in pts], [r["largest_multiplier"] for r in pts], "s", ms=3, color="C3",
               label="largest |multiplier|")
    re = [r for r in pts if r["leading_real"]]
    ax[1].plot([r["speed_hz"] for r in re], [r["leading_re"] for r in re], "k*", ms=8,
               label="leading multiplier real (> 0)")
    ax[1].axhline(1.0, color="k", lw=0.8)
    ax[1].set(xlabel="speed [Hz]", ylabel="|mu_1|", title="stability along the branch")
    if side:
        near = [r for r in pts if r["speed_hz"] > min(r["speed_hz"] for r in side["branch"]) - 0.006]
        axes[1][0].plot([r["speed_hz"] for r in near], [r["midspan_m"] * 1e3 for r in near], "-s", ms=3, color="C3",
                        label="touching branch from below (stable)")
        axes[1][0].plot([end["speed_hz"]], [end["midspan_m"] * 1e3], "*", ms=14, color="k", label="its end")
        draw_side(side, axes[1][0], ax[1], axes[1][1])
    for a in ax:
        a.grid(alpha=0.3)
        a.ticklabel_format(axis="x", useOffset=False)
        a.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def draw_side(side: dict, zoom, mult, dep) -> None:
    """The branch of ``--unstable`` (open, touching stable, touching unstable dashed; its grazings dotted; where the
    pushes from its unstable orbit end) on ``zoom`` (midspan) and ``mult`` (largest |multiplier|), and the departure
    from its unstable orbit against mu_1^k on ``dep``."""
    sb = sorted(side["branch"], key=lambda r: r["speed_hz"])
    for label, sel, style, c in (
            ("open orbits, continued down", lambda r: r["events_per_period"] == 0, "-o", "C0"),
            ("past the open grazing: touching, stable", lambda r: r["events_per_period"] > 0 and r["stable"],
             "-^", "C2"),
            ("touching, unstable (real multiplier > 1)", lambda r: r["events_per_period"] > 0 and not r["stable"],
             "--D", "k")):
        rs = [r for r in sb if sel(r)]
        if rs:
            for a, y in ((zoom, [r["midspan_m"] * 1e3 for r in rs]), (mult, [r["largest_multiplier"] for r in rs])):
                a.plot([r["speed_hz"] for r in rs], y, style, ms=3.5, color=c, mfc="none" if "un" in label else c,
                       label=label)
    for gz in side["grazings"]:
        zoom.axvline(gz["value"], color="0.6", lw=0.6, ls=":")
    after = side["checks"].get("unstable_aftermath")
    if after:
        ends = [after[k]["ends_on"] for k in ("plus", "minus") if after[k]["ends_on"]["converged"]]
        if ends:
            zoom.plot([after["speed_hz"]] * len(ends), [e["midspan_m"] * 1e3 for e in ends], "v", ms=8, mfc="none",
                      color="C2", label="where pushes from the unstable orbit end (stable)")
    zoom.set(xlabel="speed [Hz]", ylabel="midspan z, half p-p [mm]",
             title="from the open side; dotted: grazings located by the continuation")
    mult.axhline(1.0, color="k", lw=0.8)
    c = side["checks"].get("unstable_departure")
    if c:
        k = np.arange(1, c["periods"] + 1)
        dep.semilogy(k, c["relative_distance"], "o", color="k", ms=4,
                     label=f"from the unstable orbit at {c['speed_hz']:.6f} Hz")
        dep.semilogy(k, c["multiplier_re"] ** k, "-", color="k", lw=0.8,
                     label=f"mu_1^k, mu_1 = {c['multiplier_re']:.4f}")
    dep.set(xlabel="period k", ylabel="distance / initial", title="a perturbation along the leading Floquet direction")
    for a in (zoom, mult, dep):
        a.grid(alpha=0.3)
        a.ticklabel_format(axis="x", useOffset=False)
        a.legend(fontsize=7)


def side_figure(side: dict, path: Path) -> None:
    """delamination_unstable.png: the branch of ``--unstable`` alone (midspan, multipliers, departure)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(16, 4.4))
    draw_side(side, ax[0], ax[1], ax[2])
    ax[1].set(xlabel="speed [Hz]", ylabel="largest |multiplier|", title="stability (outside 1: unstable)")
    fig.suptitle(f"gravity {side['gravity']:g} m/s^2, beta {side['beta_s']:g} s, frictionless", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def figure(payload: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in payload["rows"] if r["converged"]]
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.4))
    kinds = (("open, stable", lambda r: r["events_per_period"] == 0 and r["stable"], "o", "C0"),
             ("touching, stable", lambda r: r["events_per_period"] > 0 and r["stable"], "s", "C3"),
             ("touching, unstable", lambda r: r["events_per_period"] > 0 and not r["stable"], "D", "k"))
    for label, sel, mk, c in kinds:
        rs = sorted((r for r in rows if sel(r)), key=lambda r: r["speed_hz"])
        if not rs:
            continue
        s = [r["speed_hz"] for r in rs]
        style = "--" if "unstable" in label else "-"
        face = "none" if "unstable" in label else c
        for a, y in ((ax[0], [r["midspan_m"] * 1e3 for r in rs]), (ax[1], [r["largest_multiplier"] for r in rs])):
            if "open" in label:   # two open pieces (below and above the touching band): no line across it
                y = np.array(y, dtype=float)
                cut = np.flatnonzero(np.diff(s) > 0.006) + 1
                for part_s, part_y in zip(np.split(np.array(s), cut), np.split(y, cut)):
                    a.plot(part_s, part_y, style, color=c, lw=1.2)
                a.plot(s, y, mk, color=c, ms=3, label=label)
            else:
                a.plot(s, y, style + mk, color=c, mfc=face, ms=5, lw=1.2, label=label)
    bad = [r for r in payload["rows"] if not r["converged"]]
    if bad:
        ax[0].plot([r["speed_hz"] for r in bad], [r["midspan_m"] * 1e3 for r in bad], "x", color="0.5", ms=7,
                   label="shooting not converged (last iterate)")
    ax[0].set(xlabel="speed [Hz]", ylabel="midspan z (rotating frame), half p-p [mm]",
              title=f"friction {payload['mu']:g}, beta {payload['beta_s']:g} s: resonance curve")
    ax[1].axhline(1.0, color="k", lw=0.8)
    ax[1].set(xlabel="speed [Hz]", ylabel="largest |Floquet multiplier|", title="stability (outside 1: unstable)")
    ax2 = ax[1].twinx()
    rs = sorted(rows, key=lambda r: r["speed_hz"])
    ax2.plot([r["speed_hz"] for r in rs], [r["events_per_period"] for r in rs], ".", color="C2", ms=4)
    ax2.set_ylabel("events a period (green)", color="C2")
    c = payload["checks"]
    for key, lab, col in (("unstable_departure", "from the unstable orbit", "k"),
                          ("stable_contraction", "from a stable touching orbit", "C3")):
        if key in c:
            d = c[key]
            k = np.arange(1, d["periods"] + 1)
            m = math.hypot(d["multiplier_re"], d["multiplier_im"])
            ax[2].semilogy(k, d["relative_distance"], "o", color=col, ms=4,
                           label=f"{lab} ({d['speed_hz']:.4f} Hz)")
            ax[2].semilogy(k, m ** k, "-", color=col, lw=0.8, label=f"|mu_1|^k, |mu_1| = {m:.4f}")
    ax[2].set(xlabel="period k", ylabel="distance / initial", title="transients along the leading direction")
    for a in ax:
        a.grid(alpha=0.3)
        a.ticklabel_format(axis="x", useOffset=False)
    ax[0].legend(fontsize=7)
    ax[1].legend(fontsize=7, loc="lower left")
    if c:
        ax[2].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def _speed_range(ap: argparse.ArgumentParser, flag: str, text: str) -> tuple[float, float]:
    """LOW:HIGH of ``flag`` as two finite speeds 0 < LOW < HIGH [Hz], or argparse's one-line error."""
    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError:
        ap.error(f"{flag}: {text!r} is not LOW:HIGH")
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        ap.error(f"{flag}: {text!r} needs finite speeds 0 < LOW < HIGH")
    return lo, hi


def check_options(ap: argparse.ArgumentParser, args) -> None:
    """Refuse a bad option in one line (``ap.error``: exit 2) before any flow."""
    for name, value in (("--beta", args.beta), ("--step", args.step), ("--fine", args.fine),
                        ("--touch-speed", args.touch_speed)):
        if not (math.isfinite(value) and value > 0):
            ap.error(f"{name} must be a finite number > 0, got {value!r}")
    if not (math.isfinite(args.mu) and args.mu >= 0):
        ap.error(f"--mu must be a finite friction coefficient >= 0, got {args.mu!r}")
    if args.fine > args.step:
        ap.error(f"--fine ({args.fine!r}) must not exceed --step ({args.step!r})")
    for name, value, least in (("--lead", args.lead, 0), ("--settle", args.settle, 0), ("--max-iter", args.max_iter, 1),
                               ("--periods", args.periods, 1), ("--revolutions", args.revolutions, 1)):
        if value < least:
            ap.error(f"{name} must be >= {least}, got {value}")
    try:
        dr.parse_speeds(args.speeds)
    except ValueError as exc:
        ap.error(f"--speeds: {' '.join(str(exc).split())}")
    if not (math.isfinite(args.gravity) and 0 < args.gravity <= 100):
        ap.error(f"--gravity must be a finite number in (0, 100] m/s^2, got {args.gravity!r}")
    if not (math.isfinite(args.fold_start_speed) and args.fold_start_speed > 0):
        ap.error(f"--fold-start-speed must be a finite number > 0, got {args.fold_start_speed!r}")
    lo, hi = _speed_range(ap, "--fold-range", args.fold_range)
    ulo, uhi = _speed_range(ap, "--unstable-range", args.unstable_range)
    if not args.fold_steps >= 1:
        ap.error(f"--fold-steps must be >= 1, got {args.fold_steps}")
    if not Path(args.start).is_file():
        ap.error(f"--start: no such file {args.start!r} (a touching orbit's section state, .npz)")
    if args.fold:
        # the walk to the fold's start goes up from the start orbit's speed, and the continuation starts there
        try:
            s0 = float(np.load(args.start)["speed_hz"])
        except Exception as exc:   # (any unreadable file: one line)
            ap.error(f"--start: cannot read speed_hz from {args.start!r}: {' '.join(str(exc).split())}")
        if not s0 <= args.fold_start_speed:
            ap.error(f"--fold-start-speed ({args.fold_start_speed!r} Hz) must not lie below the --start orbit's "
                     f"speed ({s0!r} Hz): the walk to it goes up")
        if not lo < args.fold_start_speed < hi:
            ap.error(f"--fold-start-speed ({args.fold_start_speed!r} Hz) must lie inside --fold-range "
                     f"{args.fold_range!r}")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mu", type=float, default=0.3, help="friction coefficient between the layers")
    ap.add_argument("--beta", type=float, default=1e-5, help="stiffness-proportional damping [s]")
    ap.add_argument("--speeds", default="22.70:22.86:33", help="LOW:HIGH:N the open orbits' speeds [Hz]")
    ap.add_argument("--touch-speed", type=float, default=22.78, help="the touching branch's start [Hz]")
    ap.add_argument("--step", type=float, default=0.0025, help="the touching branch's speed step [Hz]")
    ap.add_argument("--fine", type=float, default=0.0005, help="the refining step at the branch's ends [Hz]")
    ap.add_argument("--start", default=str(START), help="a touching orbit's section state (.npz: q0 v0 t0 speed_hz beta)")
    ap.add_argument("--settle", type=int, default=40, help="revolutions from the mapped start before shooting")
    ap.add_argument("--lead", type=int, default=20, help="revolutions before the first open orbit")
    ap.add_argument("--max-iter", type=int, default=15, help="Newton steps per orbit")
    ap.add_argument("--periods", type=int, default=20, help="the departure checks' periods")
    ap.add_argument("--revolutions", type=int, default=150, help="the motion after the unstable orbit")
    ap.add_argument("--out", default=str(ROOT / "studies" / "out" / "delamination_variants"))
    ap.add_argument("--figure", default=str(ROOT / "docs" / "figures" / "delamination_variants.png"))
    ap.add_argument("--fold", action="store_true",
                    help="instead: the frictionless touching branch at --gravity by pseudo-arclength to its end")
    ap.add_argument("--gravity", type=float, default=20.0, help="gravity [m/s^2] of --fold (the paper: 9.81)")
    ap.add_argument("--fold-start-speed", type=float, default=22.80, help="--fold's starting orbit [Hz]")
    ap.add_argument("--fold-range", default="22.72:22.84", help="--fold's LOW:HIGH speeds [Hz]")
    ap.add_argument("--fold-steps", type=int, default=80,
                    help="--fold's (and --unstable's) continuation steps each way")
    ap.add_argument("--unstable", action="store_true",
                    help="instead: the frictionless branch at --gravity continued down from its open orbit at the top "
                         "of --unstable-range through its grazings onto touching orbits, stable and unstable")
    ap.add_argument("--unstable-range", default="22.805:22.83", help="--unstable's LOW:HIGH speeds [Hz]")
    args = ap.parse_args(argv)
    check_options(ap, args)
    if args.fold and args.unstable:
        ap.error("--fold and --unstable are two runs: give one (the second draws both into delamination_fold.png)")
    return fold(args) if args.fold else unstable(args) if args.unstable else study(args)


if __name__ == "__main__":
    main()
