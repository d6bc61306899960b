"""The Jeffcott rub's resonance curve through the loss of the synchronous full annular rub (issue 36, goal 2b).

The shipped ``rub`` (a 5 kg disk on a light shaft inside a rigid ring 0.1 mm away) at friction mu and speed f:

1. **Reference** (round ring, rotating frame; ``tests/rub_reference.py``, plain NumPy): the stationary rub and the
   eigenvalues of its linearization with the contact held, over mu x speed. Reported per point: the normal force N,
   the largest real part of the eigenvalues and its mode (frequency in the rotating frame, the disk's share, the
   whirl sense of its disk motion in the inertial frame), and the disk's own mode (its motion along the ring).
   Per mu, the onset speed where the largest real part crosses 0 (Brent), and where the rub begins (N = 0: the
   free whirl reaches the clearance).
2. **Continuation** on the exact flow (polygon of ``--facets`` facets, inertial frame,
   :func:`nsfem.periodic.branch.orbit_branch`) at ``--mu`` over ``--speeds``, started from the reference's state
   turned into the inertial frame: the branch's stability and the located Neimark-Sacker point, against the
   reference's onset; at ``--onset-facets`` (default 128) the onset by Brent's method on single orbits' largest
   multiplier (the polygon's error is first order in 1 / F: the onsets' distance to the reference's halves).
3. **Transient** (exact method) started on the branch's orbit just past the onset, a little perturbed: the growth
   of the deviation from the orbit and its spectrum (the whirl's frequency), against the reference eigenvalue.

    python studies/rub_whirl.py [--quick] [--json] [--mu 0.55] [--facets 64] [--speeds 23:28]
                                [--onset-facets 128] [--transient-hz 28] [--periods 1500]

``--quick``: a coarser map, the branch over 26.5:27 Hz only (around the 64-facet onset), no onsets by single
orbits, no transient. Writes rub_whirl.json/.csv into studies/out/rub_whirl and the figure into
docs/figures/rub_whirl.png (``--quick``: rub_whirl_quick.json/.csv/.png there); ``--replot`` redraws the figure from rub_whirl.json.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from study_io import machine, save_figure, write_outputs

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from nsfem.fem.assemble import build_model  # noqa: E402
from nsfem.fem.components import lateral_turn  # noqa: E402
from nsfem.integrate import ContactSystem  # noqa: E402
from nsfem.reduce import scene_reduction  # noqa: E402
from nsfem.scene.load import load_scene  # noqa: E402
from nsfem.sensors import hermite_row  # noqa: E402
from rub_reference import held_pencil, ring_rows, round_rub  # noqa: E402

OUT = ROOT / "studies" / "out" / "rub_whirl"
FIGURE = ROOT / "docs" / "figures" / "rub_whirl.png"


class Rub:
    """The shipped rub at friction mu (one model and reduction; the system at any speed from them)."""

    def __init__(self, mu: float, facets: int = 64, frame: str = "rotating", extra: tuple[str, ...] = ()):
        self.mu, self.facets = float(mu), int(facets)
        self.scene = load_scene("rub", [f"stator.0.friction={mu}", f"stator.0.facets={facets}",
                                        f"rotation.frame={frame}", *extra])
        self.model = build_model(self.scene)
        self.red = scene_reduction(self.scene.reduction, self.model)
        T = np.asarray(self.red.T)
        turn = lateral_turn(self.model.spaces, T.shape[0]) @ T
        self.J = np.linalg.lstsq(T, turn, rcond=None)[0]      # the frame's quarter turn in reduced coordinates
        seg = next(iter(self.model.spaces))
        #: (y, z) at a quarter of the span (x = 0.2 m): the shaft's antisymmetric modes have the disk at a node
        self.probe = np.vstack([(hermite_row(self.model, seg, f, 0.2) @ T).ravel() for f in ("V", "W")])

    def system(self, speed_hz: float) -> ContactSystem:
        return ContactSystem.from_scene(self.scene, self.model, self.red, speed_hz=float(speed_hz))


def free_whirl(rub: Rub, speed_hz: float) -> float:
    """|D Q^-1 f0| / c: the contact-free synchronous whirl's disk radius over the clearance (rotating frame)."""
    R = rub.system(speed_hz)
    D, c, _ = ring_rows(R.contacts.JN, R.contacts.jN)
    return float(np.linalg.norm(D @ np.linalg.solve(R.Q, R.f0)) / c)


def reference(rub: Rub, speed_hz: float) -> dict | None:
    """The round ring's stationary rub at the speed and its held linearization's eigenvalues (None: no rub)."""
    R = rub.system(speed_hz)
    D, c, _ = ring_rows(R.contacts.JN, R.contacts.jN)
    s = math.copysign(1.0, R.omega)
    try:
        st = round_rub(R.Q, R.f0, D, c, rub.mu, s)
    except ValueError:
        return None
    Mr, Cr, Kr = held_pencil(R.M, R.C, R.Q, D, st, c, rub.mu)
    m = Mr.shape[0]
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-np.linalg.solve(Mr, Kr), -np.linalg.solve(Mr, Cr)]])
    lam, V = np.linalg.eig(A)
    dq = sla.null_space((D.T @ st.n)[None, :]) @ V[:m]
    du = D @ dq                                                # the disk's motion (2 x modes, complex)
    share = np.linalg.norm(du, axis=0) / (np.linalg.norm(D, 2) * np.linalg.norm(dq, axis=0))
    k = int(np.argmax(lam.real + 1e-9 * lam.imag))             # of a conjugate pair, the one with Im > 0
    disk = int(np.argmax(share + 1e-9 * np.sign(lam.imag)))
    return {"speed_hz": float(speed_hz), "mu": rub.mu, "N": st.N, "state": st, "system": R, "D": D, "c": c,
            "lam_max": complex(lam[k]), "share_max": float(share[k]), "sense": whirl_sense(rub.probe @ dq[:, k], lam[k], R.omega),
            "lam_disk": complex(lam[disk])}


def whirl_sense(du: np.ndarray, lam: complex, omega: float) -> dict:
    """The disk's motion Re(du e^{lambda t}) of a mode (rotating frame, Im lambda = w >= 0) in the inertial frame:
    z = y + i z' splits into a forward part at w + Omega and a backward one at w - Omega (negative: backward);
    returns their frequencies [Hz] and the backward share |b| / (|a| + |b|)."""
    w = abs(lam.imag)
    u = du if lam.imag >= 0 else du.conj()
    a = abs(u[0] + 1j * u[1]) / 2.0                 # e^{+i w t} in the rotating frame
    b = abs(u[0].conjugate() + 1j * u[1].conjugate()) / 2.0   # e^{-i w t}
    return {"forward_hz": (w + omega) / (2 * math.pi), "backward_hz": (w - omega) / (2 * math.pi),
            "backward_share": float(b / (a + b))}


def onset(rub: Rub, lo: float, hi: float) -> float | None:
    """The speed in [lo, hi] where the largest real part crosses 0 (None: no sign change)."""
    def g(f):
        r = reference(rub, f)
        return -1.0 if r is None else r["lam_max"].real
    glo, ghi = g(lo), g(hi)
    if glo * ghi > 0:
        return None
    return float(brentq(g, lo, hi, xtol=1e-6))


def rub_start(rub: Rub, lo: float, hi: float) -> float:
    """The speed where the free whirl reaches the clearance (N = 0: the rub begins), in [lo, hi]."""
    return float(brentq(lambda f: free_whirl(rub, f) - 1.0, lo, hi, xtol=1e-6))


def stability_map(mus, speeds) -> tuple[list[dict], list[dict]]:
    rows, onsets = [], []
    for mu in mus:
        rub = Rub(mu)
        start = rub_start(rub, 10.0, 22.4)
        for f in speeds:
            r = reference(rub, f)
            if r is None:
                rows.append({"mu": mu, "speed_hz": f, "rub": False})
                continue
            rows.append({"mu": mu, "speed_hz": f, "rub": True, "N": r["N"], "re_max": r["lam_max"].real,
                         "f_max_hz": r["lam_max"].imag / (2 * math.pi), "share_max": r["share_max"],
                         "re_disk": r["lam_disk"].real, "f_disk_hz": abs(r["lam_disk"].imag) / (2 * math.pi)})
        on = onset(rub, start + 1e-3, max(speeds))
        item = {"mu": mu, "rub_start_hz": start, "onset_hz": on}
        if on is not None:
            r = reference(rub, on)
            item.update(f_rotating_hz=r["lam_max"].imag / (2 * math.pi), share=r["share_max"], **r["sense"],
                        N=r["N"])
        onsets.append(item)
    return rows, onsets


def inertial_section(rub_i: Rub, ref: dict, facets: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(t0, q, q'): the round-ring state turned into the inertial frame at the first t0 >= 0 with the disk at a
    facet's middle (away from the corner events; as tests/test_periodic_rub.py)."""
    st, w = ref["state"], ref["system"].omega
    t0 = ((-math.atan2(st.n[1], st.n[0])) % (2.0 * math.pi / facets)) / w
    q = sla.expm(w * t0 * rub_i.J) @ st.q
    return t0, q, w * rub_i.J @ q


def continuation(mu: float, facets: int, lo: float, hi: float, steps: int, say) -> dict:
    """The exact flow's orbit branch over speed (polygon, inertial frame) from the reference at lo, in one piece.

    The orbit's phase drifts with the speed, a corner passage of the polygon every ~0.8 Hz onto any fixed section;
    the branch moves its section off them as they come (``reanchors``: where and to which t0)."""
    from nsfem.periodic.branch import orbit_branch

    rub_r, rub_i = Rub(mu, facets), Rub(mu, facets, "inertial")
    t = time.perf_counter()
    t0, q, v = inertial_section(rub_i, reference(rub_r, lo), facets)
    br = orbit_branch(rub_i.system, lambda f: 1.0 / f, q, v, lo, hi, key="rotation.speed_hz", t0=t0,
                      max_steps=steps, switch=False,
                      on_point=lambda bp, m: say(f"  {bp.p:.6g} Hz: max |multiplier| {np.abs(bp.multipliers).max():.6f}"
                                                 f" (section t0 {1e3 * bp.t0_s:.4f} ms) "
                                                 f"[{time.perf_counter() - t:.0f} s]"))
    pts = []
    for q_ in br.points:
        mu_ = np.array([complex(*m) for m in q_["multipliers"]])
        pts.append({"speed_hz": q_["rotation.speed_hz"], "t0_s": q_["t0_s"], "stable": q_["stable"], "loss": q_["loss"],
                    "converged": q_["converged"], "max_modulus": float(np.abs(mu_).max()),
                    "outside": int((np.abs(mu_) > 1.0 + 1e-6).sum()),
                    "rate_per_s": float(np.log(np.abs(mu_).max()) * q_["rotation.speed_hz"])})
    return {"mu": mu, "facets": facets, "points": pts,
            "bifurcations": [{"kind": b["kind"], "value": b["value"]} for b in br.bifurcations],
            "reanchors": [{k: r[k] for k in ("value", "t0_s", "forced")} for r in br.reanchors],
            "stop": br.stop, "reason": br.reason, "wall_s": time.perf_counter() - t}


def orbit_onset(mu: float, facets: int, lo: float, hi: float, say) -> dict:
    """The speed in [lo, hi] where the polygon orbit's largest multiplier reaches the unit circle, by Brent's method
    on ln|mu_max| (each value a shooting from the reference, as :func:`transient`): a check of the continuation's
    located point, and the onset at facet counts where a continuation is too long."""
    from nsfem.periodic import periodic_orbit

    rub_r, rub_i = Rub(mu, facets), Rub(mu, facets, "inertial")
    t = time.perf_counter()
    seen = []

    def g(f: float) -> float:
        ref = reference(rub_r, f)
        t0, q, v = inertial_section(rub_i, ref, facets)
        orbit = periodic_orbit(rub_i.system(f), 1.0 / f, q, v, t0=t0)
        if not orbit.converged:
            raise RuntimeError(f"no orbit at {f} Hz ({facets} facets): residual {orbit.residual:.3g}")
        k = int(np.argmax(np.abs(orbit.multipliers)))
        seen.append((f, orbit.multipliers[k]))
        say(f"  {facets} facets, {f:.6f} Hz: largest multiplier {orbit.multipliers[k]:.6f} "
            f"[{time.perf_counter() - t:.0f} s]")
        return float(np.log(abs(orbit.multipliers[k])))

    f = float(brentq(g, lo, hi, xtol=1e-4))
    m = min(seen, key=lambda x: abs(x[0] - f))[1]
    return {"mu": mu, "facets": facets, "onset_hz": f, "multiplier": [m.real, m.imag],
            "argument_rad": float(np.angle(m)), "wall_s": time.perf_counter() - t}


def transient(mu: float, facets: int, speed_hz: float, periods: int, say) -> dict:
    """The exact flow from the branch's orbit at ``speed_hz`` (past the onset), its section state perturbed by 1e-4
    of its size along the unstable multiplier's direction: the deviation from the orbit at a quarter of the span
    (y + i z, inertial frame) over ``periods`` periods, its growth rate (a least-squares line through the log of
    its envelope per period) and its dominant frequency (FFT of the last half; positive: forward)."""
    from nsfem.periodic import periodic_orbit
    from nsfem.periodic.flow import flow

    rub_r, rub_i = Rub(mu, facets), Rub(mu, facets, "inertial")
    ref = reference(rub_r, speed_hz)
    t0, q, v = inertial_section(rub_i, ref, facets)
    T = 1.0 / speed_hz
    system = rub_i.system(speed_hz)
    t = time.perf_counter()
    orbit = periodic_orbit(system, T, q, v, t0=t0)
    mods = np.abs(orbit.multipliers)
    say(f"  orbit at {speed_hz:g} Hz: converged {orbit.converged}, largest |multiplier| {mods.max():.6f} "
        f"({np.log(mods.max()) / T:+.4f} 1/s)")
    samples = 4 * facets                                             # per period: 1.6e4 /s at 25 Hz (Nyquist 8 kHz)
    base = flow(system, orbit.t0, orbit.q0, orbit.v0, T, jacobian=False, output_dt=T / samples).result
    lam, V = np.linalg.eig(orbit.monodromy)
    k = int(np.argmax(np.abs(lam)))
    dx = orbit.directions @ np.real(V[:, k]) if orbit.directions.shape[1] == lam.size else np.real(V[:, k])
    x0 = np.concatenate([orbit.q0, orbit.v0])
    dx *= 1e-4 * np.abs(x0).max() / np.abs(dx).max()
    n = system.n
    run = flow(system, orbit.t0, orbit.q0 + dx[:n], orbit.v0 + dx[n:], periods * T, jacobian=False,
               output_dt=T / samples).result
    m = min(run.q.shape[1], samples * periods)
    orbit_q = np.tile(base.q[:, :samples], periods)[:, :m]
    dev = rub_i.probe @ (run.q[:, :m] - orbit_q)
    z = dev[0] + 1j * dev[1]
    env = np.abs(z[: samples * (m // samples)]).reshape(-1, samples).max(axis=1)
    per = np.arange(env.size) * T
    rate = float(np.polyfit(per[env.size // 4:], np.log(env[env.size // 4:]), 1)[0])
    half = z[m // 2:] * np.hanning(m - m // 2)
    spec = np.abs(np.fft.fft(half))
    freq = np.fft.fftfreq(half.size, T / samples)
    j = int(np.argmax(spec))
    out = {"speed_hz": speed_hz, "periods": periods, "orbit_converged": bool(orbit.converged),
           "largest_modulus": float(mods.max()), "orbit_rate_per_s": float(np.log(mods.max()) / T),
           "transient_rate_per_s": rate, "whirl_hz": float(freq[j]),
           "resolution_hz": float(1.0 / (half.size * T / samples)),
           "reference_rate_per_s": ref["lam_max"].real, "reference_forward_hz": ref["sense"]["forward_hz"],
           "reference_backward_hz": ref["sense"]["backward_hz"], "wall_s": time.perf_counter() - t}
    radius = np.hypot(*(ref["D"] @ run.q[:, max(0, m - 10 * samples):m])) / ref["c"]
    out.update(last10_radius_min=float(radius.min()), last10_radius_max=float(radius.max()),
               last10_deviation_max=float(np.abs(z[max(0, m - 10 * samples):]).max()),
               probe_orbit_max=float(np.abs(rub_i.probe @ base.q).max()))
    say(f"  transient over {periods} periods: growth {rate:+.4f} 1/s (orbit's multiplier {out['orbit_rate_per_s']:+.4f}),"
        f" whirl {freq[j]:+.2f} Hz (+- {out['resolution_hz']:.2f}; reference forward {out['reference_forward_hz']:.2f},"
        f" backward {out['reference_backward_hz']:.2f} Hz) [{out['wall_s']:.0f} s]; last 10 periods: disk radius "
        f"{out['last10_radius_min']:.5f}..{out['last10_radius_max']:.5f} c, deviation at x = 0.2 m "
        f"{out['last10_deviation_max']:.3g} m (orbit {out['probe_orbit_max']:.3g} m)")
    return out


def figure(rows: list[dict], onsets: list[dict], branches: list[dict], mu_curve: float, path: Path,
           orbit_onsets: list[dict] = ()) -> None:
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.5, 7.5), sharex=True)
    for mu in sorted({r["mu"] for r in rows}):
        rr = [r for r in rows if r["mu"] == mu and r["rub"]]
        f = np.array([r["speed_hz"] for r in rr])
        N = np.array([r["N"] for r in rr])
        re = np.array([r["re_max"] for r in rr])
        st = re < 0
        line, = ax1.plot(np.where(st, f, np.nan), np.where(st, N, np.nan), "-", lw=1.5 if mu == mu_curve else 0.8,
                         label=f"mu = {mu:g}")
        ax1.plot(np.where(~st, f, np.nan), np.where(~st, N, np.nan), "--", color=line.get_color(),
                 lw=1.5 if mu == mu_curve else 0.8)
        ax2.plot(f, re, "-", color=line.get_color(), lw=0.8)
    for o in onsets:
        if o.get("onset_hz") is not None:
            ax1.plot(o["onset_hz"], o["N"], "o", mfc="none", color="k")
    for b in branches:
        f = np.array([p["speed_hz"] for p in b["points"]])
        ax2.plot(f, [p["rate_per_s"] for p in b["points"]], "k.", ms=4,
                 label=f"exact flow, {b['facets']} facets, mu = {b['mu']:g}: ln|multiplier| / T")
        for bif in b["bifurcations"]:
            ax2.axvline(bif["value"], color="k", ls=":", lw=0.8)
            ax2.plot(bif["value"], 0.0, "k^", label=f"{bif['kind']} located on {b['facets']} facets: "
                                                    f"{bif['value']:.3f} Hz")
    for o in orbit_onsets:
        ax2.plot(o["onset_hz"], 0.0, "kx", ms=8, label=f"onset on {o['facets']} facets (single orbits): "
                                                       f"{o['onset_hz']:.3f} Hz")
    for o in onsets:
        if o["mu"] == mu_curve and o.get("onset_hz") is not None:
            ax2.plot(o["onset_hz"], 0.0, "ko", mfc="none", label=f"round ring's onset, mu = {o['mu']:g}: "
                                                                 f"{o['onset_hz']:.3f} Hz")
    ax1.set_ylabel("normal force N [N] (round ring)")
    ax1.set_title("synchronous full annular rub: stable solid, unstable dashed, o = onset")
    ax1.legend(fontsize=7, ncol=2)
    ax2.axhline(0.0, color="grey", lw=0.5)
    ax2.set_xlabel("speed [Hz]")
    ax2.set_ylabel("largest growth rate [1/s]\n(round ring: max Re lambda)")
    ax2.set_ylim(-8, 6)
    if branches:
        ax2.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--mu", type=float, default=0.55, help="the friction of the continuation")
    ap.add_argument("--facets", type=int, nargs="*", default=[64])
    ap.add_argument("--speeds", default=None, help="the continuation's range LOW:HIGH [Hz]")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--no-branch", action="store_true")
    ap.add_argument("--replot", action="store_true", help="redraw the figure from the saved JSON only")
    ap.add_argument("--onset-facets", type=int, nargs="*", default=None,
                    help="facet counts whose onset is found by Brent's method on single orbits (default 128; quick: none)")
    ap.add_argument("--onset-range", default="25.3:27", help="LOW:HIGH [Hz] bracketing those onsets")
    ap.add_argument("--transient-hz", type=float, default=None,
                    help="a transient at this speed past the onset (default 28; quick: none)")
    ap.add_argument("--periods", type=int, default=1500)
    a = ap.parse_args(argv)
    if a.replot:   # the figure again from the saved JSON (no computation)
        d = json.loads((OUT / "rub_whirl.json").read_text())
        figure(d["map"], d["onsets"], d["branches"], a.mu, FIGURE, d.get("orbit_onsets", []))
        return 0
    if not (math.isfinite(a.mu) and 0.0 < a.mu <= 2.0):
        ap.error(f"--mu must be a friction coefficient in (0, 2], got {a.mu!r}")
    if any(F < 8 for F in a.facets + (a.onset_facets or [])) or a.steps < 1 or a.periods < 8:
        ap.error("--facets and --onset-facets must be at least 8, --steps at least 1, --periods at least 8")
    if a.speeds is None:
        a.speeds = "26.5:27" if a.quick else "23:28"
    for name in ("speeds", "onset_range"):
        try:
            lo_, hi_ = (float(x) for x in getattr(a, name).split(":"))
        except ValueError:
            ap.error(f"--{name.replace('_', '-')} must be LOW:HIGH in Hz, got {getattr(a, name)!r}")
        if not (math.isfinite(lo_) and math.isfinite(hi_) and 16.0 <= lo_ < hi_ <= 60.0):
            ap.error(f"--{name.replace('_', '-')} {getattr(a, name)}: need 16 <= LOW < HIGH <= 60 Hz (the rub exists "
                     "from 15.67 Hz)")
    if a.transient_hz is not None and not (math.isfinite(a.transient_hz) and 16.0 <= a.transient_hz <= 60.0):
        ap.error(f"--transient-hz must be a speed in [16, 60] Hz, got {a.transient_hz!r}")
    say = (lambda s: print(s, file=sys.stderr)) if a.json else print
    mus = [0.1, 0.3, 0.5, 0.55, 0.6] if a.quick else [0.1, 0.2, 0.3, 0.4, 0.5, 0.52, 0.55, 0.58, 0.6]
    speeds = list(np.round(np.linspace(16.0, 40.0, 25 if a.quick else 97), 6))
    t = time.perf_counter()
    rows, onsets = stability_map(mus, speeds)
    say(f"reference map: {len(rows)} points in {time.perf_counter() - t:.1f} s")
    for o in onsets:
        say(f"mu {o['mu']:g}: rub from {o['rub_start_hz']:.4f} Hz; onset "
            + ("none up to %g Hz" % max(speeds) if o["onset_hz"] is None else
               f"{o['onset_hz']:.4f} Hz, rotating-frame {o['f_rotating_hz']:.2f} Hz, disk share {o['share']:.3f}, "
               f"inertial forward {o['forward_hz']:.2f} / backward {o['backward_hz']:.2f} Hz, "
               f"backward share {o['backward_share']:.3f}"))
    branches = []
    if not a.no_branch:
        lo, hi = (float(x) for x in a.speeds.split(":"))
        for F in a.facets:
            say(f"continuation: {F} facets, mu {a.mu:g}, {lo:g}..{hi:g} Hz")
            branches.append(continuation(a.mu, F, lo, hi, a.steps, say))
            say(f"  bifurcations {branches[-1]['bifurcations']}, {len(branches[-1]['reanchors'])} section moves, "
                f"stop {branches[-1]['stop']} ({branches[-1]['wall_s']:.0f} s)")
    found = []
    lo, hi = (float(x) for x in a.onset_range.split(":"))
    for F in ([] if a.quick else [128]) if a.onset_facets is None else a.onset_facets:
        say(f"onset by single orbits: {F} facets, mu {a.mu:g}")
        found.append(orbit_onset(a.mu, F, lo, hi, say))
        say(f"  {found[-1]['onset_hz']:.5f} Hz ({found[-1]['wall_s']:.0f} s)")
    runs = []
    if a.transient_hz is None and not a.quick:
        a.transient_hz = 28.0
    if a.transient_hz is not None:
        say(f"transient: {a.facets[0]} facets, mu {a.mu:g}, {a.transient_hz:g} Hz")
        runs.append(transient(a.mu, a.facets[0], a.transient_hz, a.periods, say))
    payload = {"map": rows, "onsets": onsets, "branches": branches, "orbit_onsets": found, "transients": runs, "machine": machine(),
               "wall_s": time.perf_counter() - t}
    write_outputs(OUT, "rub_whirl_quick" if a.quick else "rub_whirl", rows, payload)
    figure(rows, onsets, branches, a.mu, OUT / "rub_whirl_quick.png" if a.quick else FIGURE, found)
    if a.json:
        print(json.dumps(payload))
    return 0


if __name__ == "__main__":
    sys.exit(main())
