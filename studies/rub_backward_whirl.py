"""The Jeffcott rub on an ELASTIC ring through the onset of backward whirl (issue 36, goal 2b).

The shipped ``rub`` (5 kg disk at midspan of a light pinned-pinned shaft, 40 N s/m damper at the disk, beta = 1e-5)
with its ring on a radial mount of stiffness k_s (``stator.0.stiffness``, undamped) at friction mu. On the rigid
ring the synchronous full annular rub loses stability only by a Hopf point of the shaft's second bending mode
(``studies/rub_whirl.py``); on a compliant ring the classical mechanism appears (Black 1968; Crandall 1990): the
friction mu N along the ring, with N = k_s (r - c0), acts as a cross-coupled stiffness that feeds a BACKWARD whirl
of the rotor on the ring (below sqrt((k + k_s) / m): the ring is stiff radially only) against the damping.

*The closed form* (Jeffcott rotor: modal mass m, shaft stiffness k, external damping c_e, internal c_i, unbalance
m_u e; massless isotropic ring k_s at clearance c0, Coulomb mu). In the frame turning at Omega, w = y + i z:

    m (w'' + 2 i Omega w' - Omega^2 w) + c_e (w' + i Omega w) + c_i w' + k w = m_u e Omega^2 - N (1 + i mu) w / |w|

with N = k_s (|w| - c0) while |w| > c0 (the surface slips forward: friction mu N along -t). The synchronous rub
is a rest point, r = |w| from |k - m Omega^2 + N / r + i (c_e Omega + mu N / r)| r = m_u e Omega^2. A perturbation
e^{i phi} (xi + i eta) (radial, along the ring) changes the ring's force by -(1 + i mu)(k_s xi + i (N / r) eta): the
radial spring and the force turning with the contact point. The 4 x 4 system m x'' + (c I + 2 m Omega J) x' + K x = 0,
c = c_e + c_i, K = [[k - m Omega^2 + k_s, -(c_e Omega + mu N / r)], [c_e Omega + mu k_s, k - m Omega^2 + N / r]], has
det(m l^2 + ...) = a4 l^4 + a3 l^3 + a2 l^2 + a1 l + a0 with a4 = m^2, a3 = 2 m c, a2 = m tr K + c^2 + 4 m^2 Omega^2,
a1 = c tr K + 2 m Omega (2 c_e Omega + mu (k_s + N / r)), a0 = K_rr K_tt + (c_e Omega +
mu N / r)(c_e Omega + mu k_s). Routh-Hurwitz: stable iff all a_i > 0, D2 = a3 a2 - a4 a1 > 0 and
D3 = a1 D2 - a3^2 a0 > 0; the onset is D3 = 0 (a Hopf point: l = i w, w^2 = a1 / a3). The skew part of K,
mu (k_s + N / r) / 2, is a cross-coupled stiffness that pushes against the spin: it damps forward whirl and drives
backward whirl (a mode at w in space, m l^2 + c l + k + i q = 0: Re l = -(c w + q) / (2 m w), negative w backward).
At onset the eigenvector (xi, eta) e^{i w t} moves the disk as a e^{i (w + Omega) t} + b e^{-i (w - Omega) t} in
space, a = (xi + i eta) / 2, b = conj(xi - i eta) / 2: backward at w - Omega where |b| > |a|.

1. **Closed form** (``tests/rub_reference.py``: :class:`Jeffcott`, :func:`hurwitz`, :func:`jeffcott_onset`): the
   Jeffcott rotor (the model's first mode: modal mass and stiffness with the disk's displacement as coordinate,
   c_e the damper, c_i = beta k the shaft's internal damping) in the rotating frame: the synchronous rub's radius,
   the 4 x 4 linearization (slip, N = k_s (r - c0), the force turning with the contact point), its Routh-Hurwitz
   condition D3 > 0, the onset speed per mu, the whirl frequency w = sqrt(a1 / a3) and its sense in space.
2. **Reduced model's round ring** (``elastic_rub``, ``elastic_ring_operators``: every mode of the 13-coordinate
   Craig-Bampton model): the same onset with the shaft's mass distribution, gyroscopics and second mode.
3. **Exact flow** on the 64-gon (and 128-gon) elastic ring, inertial frame (the polygon turns past the disk, so
   its facets' and corners' laws average to the round ring's, the error second order in 1 / F; in the rotating
   frame the equilibrium rests on one facet (tangential stiffness 0) or in one corner (k_s), neither the round
   ring's N / r: that frame's equilibrium does not converge to the round ring's stability): the onset by Brent's
   method on single orbits' largest multiplier (at ``--mu`` on each of ``--facets``, and at the map's other
   frictions on 64 facets), the branch over speed with its located Neimark-Sacker point
   (:func:`nsfem.periodic.branch.orbit_branch`), and a transient past the onset: its growth rate, whirl frequency in
   space (FFT of the disk's deviation, y + i z: negative = backward) and the state it goes to.

    python studies/rub_backward_whirl.py [--quick] [--json] [--stiffness 2e6] [--mu 0.03] [--facets 64 128]
                                         [--transient-hz 24] [--periods 300]
                                         [--steps 20] [--replot]

``--quick``: the closed-form and reduced maps only. Writes studies/out/rub_backward_whirl/rub_backward_whirl.json/.csv
and docs/figures/rub_backward_whirl.png.
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

from nsfem.sensors import hermite_row  # noqa: E402
from rub_reference import (Jeffcott, elastic_ring_operators, elastic_rub, jeffcott_onset)  # noqa: E402
from rub_whirl import Rub, inertial_section as turned_section  # noqa: E402

OUT = ROOT / "studies" / "out" / "rub_backward_whirl"
FIGURE = ROOT / "docs" / "figures" / "rub_backward_whirl.png"


class ElasticRub(Rub):
    """The shipped rub on an undamped elastic ring (k_s, mu, facets, frame): one model and reduction
    (:class:`rub_whirl.Rub` with the ring's mount), and the disk centre's rows."""

    def __init__(self, stiffness: float, mu: float, facets: int = 64, frame: str = "rotating"):
        super().__init__(mu, facets, frame, extra=(f"stator.0.stiffness={stiffness}", "stator.0.damping=0"))
        self.stiffness = float(stiffness)
        T = np.asarray(self.red.T)
        seg = next(iter(self.model.spaces))
        #: the disk centre (y, z) at x = 0.4 m (the sensors disk_y, disk_z)
        self.disk = np.vstack([(hermite_row(self.model, seg, f, 0.4) @ T).ravel() for f in ("V", "W")])


def modal_jeffcott(rub: ElasticRub) -> Jeffcott:
    """The Jeffcott rotor of the model's first bending mode, the disk's displacement its coordinate: m = phi^T M phi,
    k = phi^T K phi with D phi = (1, 0) (D the ring's rows), c_e = phi^T C_b phi (the damper), c_i = alpha m + beta k (the
    scene's Rayleigh damping, which turns with the shaft; alpha = 0 on the rub), the unbalance m_u e at the disk (its modal force, phi = 1 there)."""
    T = np.asarray(rub.red.T)
    M, K = T.T @ rub.model.M_full @ T, T.T @ rub.model.K_full @ T
    lam, V = sla.eigh(K, M)
    R = rub.system(20.0)
    D = np.asarray(R.rings[0].P)
    # the first mode's pair spans a plane; take the combination that moves the disk along D's first row
    pair = V[:, :2]
    phi = pair @ np.linalg.solve(D @ pair, np.array([1.0, 0.0]))
    alpha, beta = rub.scene.damping.rayleigh
    k = float(phi @ K @ phi)
    return Jeffcott(m=float(phi @ M @ phi), k=k, c_e=float(phi @ T.T @ rub.model.C_bearing @ T @ phi),
                    c_i=beta * k + alpha * float(phi @ M @ phi),
                    unbalance=float(rub.model.stack.unbalances[0].magnitude),
                    k_s=rub.stiffness, clearance=float(R.rings[0].clearance), mu=rub.mu)


def reduced_reference(rub: ElasticRub, speed_hz: float) -> dict | None:
    """The reduced model's rub on the elastic ROUND ring at the speed (rotating frame) and the eigenvalue of largest
    real part of its linearization, with the disk's whirl in space (None: no rub)."""
    R = rub.system(speed_hz)
    ring = R.rings[0]
    D = np.asarray(ring.P)
    s = math.copysign(1.0, R.omega)
    try:
        st = elastic_rub(R.Q, R.f0, D, float(ring.clearance), rub.mu, s, rub.stiffness)
    except ValueError:
        return None
    r = float(np.linalg.norm(D @ st.q))
    K, C = elastic_ring_operators(st, r, rub.mu, rub.stiffness, 0.0)
    n = R.n
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(R.M, R.Q + D.T @ K @ D), -np.linalg.solve(R.M, R.C + D.T @ C @ D)]])
    lam, V = np.linalg.eig(A)
    k = int(np.argmax(lam.real + 1e-9 * lam.imag))         # of a conjugate pair, the one with Im > 0
    u = D @ V[:n, k]                                         # the disk's motion, rotating frame, e^{i w t}
    x = u if lam[k].imag >= 0 else u.conj()
    fwd, bwd = abs(x[0] + 1j * x[1]) / 2.0, abs(x[0] - 1j * x[1]) / 2.0
    w = abs(lam[k].imag)
    return {"speed_hz": float(speed_hz), "N": st.N, "radius": r, "state": st, "system": R, "D": D,
            "lam": complex(lam[k]), "forward_hz": (w + R.omega) / (2 * math.pi),
            "backward_hz": (w - R.omega) / (2 * math.pi), "backward_share": float(bwd / (fwd + bwd))}


def reduced_onset(rub: ElasticRub, lo: float, hi: float) -> dict | None:
    """The speed in [lo, hi] Hz where the reduced model's largest real part crosses 0 (None: no sign change)."""
    def g(f: float) -> float:
        ref = reduced_reference(rub, f)
        return -1.0 if ref is None else ref["lam"].real

    if g(lo) * g(hi) > 0:
        return None
    f = float(brentq(g, lo, hi, xtol=1e-9))
    ref = reduced_reference(rub, f)
    return {"speed_hz": f, "N": ref["N"], "radius": ref["radius"], "w_rotating": abs(ref["lam"].imag),
            "forward_hz": ref["forward_hz"], "backward_hz": ref["backward_hz"],
            "backward_share": ref["backward_share"]}


def rub_start(jeff: Jeffcott) -> float:
    """The speed [Hz] where the free whirl reaches the clearance (the rub begins), below the critical speed."""
    def excess(f: float) -> float:
        w = 2 * math.pi * f
        return jeff.unbalance * w ** 2 - abs(complex(jeff.k - jeff.m * w ** 2, jeff.c_e * w)) * jeff.clearance

    return float(brentq(excess, 1.0, math.sqrt(jeff.k / jeff.m) / (2 * math.pi), xtol=1e-10))


def friction_at_rub_start(jeff: Jeffcott, start_hz: float) -> float:
    """The friction above which the rub is unstable from its beginning (D3 = 0 as N -> 0, 1e-6 Hz into the rub)."""
    from rub_reference import hurwitz

    w = 2 * math.pi * (start_hz + 1e-6)

    def d3(mu: float) -> float:
        a = Jeffcott(**{**vars(jeff), "mu": mu}).characteristic(w)
        return hurwitz(a)[1] / (a[0] * a[2] ** 2)

    return float(brentq(d3, 0.0, 1.0, xtol=1e-12))


def inertial_section(rub_i: ElasticRub, ref: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """(t0, q, q'): the round ring's rotating-frame state turned into the inertial frame at the first t0 >= 0 with
    the disk at a facet's middle (:func:`rub_whirl.inertial_section`)."""
    return turned_section(rub_i, ref, rub_i.facets)


def exact_orbit(rub_r: ElasticRub, rub_i: ElasticRub, speed_hz: float, **kw):
    """The inertial-frame periodic orbit on the polygon at the speed, shot from the round ring's state."""
    from nsfem.periodic import periodic_orbit

    ref = reduced_reference(rub_r, speed_hz)
    t0, q, v = inertial_section(rub_i, ref)
    return periodic_orbit(rub_i.system(speed_hz), 1.0 / speed_hz, q, v, t0=t0, **kw), ref


def exact_onset(stiffness: float, mu: float, facets: int, lo: float, hi: float, say) -> dict:
    """The speed in [lo, hi] Hz where the polygon orbit's largest multiplier reaches the unit circle (Brent's method
    on ln|mu_max|, each value a shooting from the round ring's state), with the multiplier there."""
    rub_r, rub_i = ElasticRub(stiffness, mu, facets), ElasticRub(stiffness, mu, facets, "inertial")
    t = time.perf_counter()
    seen = []

    def g(f: float) -> float:
        orbit, _ = exact_orbit(rub_r, rub_i, f)
        if not orbit.converged:
            raise RuntimeError(f"no orbit at {f} Hz ({facets} facets): residual {orbit.residual:.3g}")
        k = int(np.argmax(np.abs(orbit.multipliers)))
        seen.append((f, orbit.multipliers[k], orbit.events_per_period))
        say(f"  {facets} facets, {f:.6f} Hz: largest multiplier {orbit.multipliers[k]:.6f}, "
            f"{orbit.events_per_period} events [{time.perf_counter() - t:.0f} s]")
        return float(np.log(abs(orbit.multipliers[k])))

    f = float(brentq(g, lo, hi, xtol=1e-5))
    _, m, events = min(seen, key=lambda x: abs(x[0] - f))
    # the multiplier's argument is w T mod 2 pi: the whirl frequency in space up to multiples of the speed
    return {"mu": mu, "facets": facets, "onset_hz": f, "multiplier": [m.real, m.imag],
            "argument_rad": float(np.angle(m)), "events_per_period": int(events), "orbits": len(seen),
            "wall_s": time.perf_counter() - t}


def transient(stiffness: float, mu: float, facets: int, speed_hz: float, periods: int, say,
              kick: float = 1e-4) -> dict:
    """The exact flow (inertial frame) from the polygon orbit at ``speed_hz`` past the onset, its section state moved
    by ``kick`` of its size along the unstable multiplier's eigenvector, over ``periods`` periods (or until the exact
    method stops): the disk's deviation from the orbit z = dy + i dz (the sensors disk_y, disk_z; inertial frame),
    its growth rate (a least-squares line through the log of its per-period maximum while below 1e-2 of the
    clearance: the linear phase) and its spectrum over that phase (FFT, Hann window: negative frequency = backward
    whirl), against the round ring's eigenvalue; then the disk's radius over the last 10 periods run."""
    from nsfem.periodic.flow import flow

    rub_r, rub_i = ElasticRub(stiffness, mu, facets), ElasticRub(stiffness, mu, facets, "inertial")
    T = 1.0 / speed_hz
    t = time.perf_counter()
    orbit, ref = exact_orbit(rub_r, rub_i, speed_hz)
    mods = np.abs(orbit.multipliers)
    say(f"  orbit at {speed_hz:g} Hz: converged {orbit.converged}, largest |multiplier| {mods.max():.6f} "
        f"({np.log(mods.max()) / T:+.4f} 1/s; round ring {ref['lam'].real:+.4f} 1/s)")
    system = rub_i.system(speed_hz)
    samples = 2 * facets                                   # per period: 5.6 kHz at 22 Hz (Nyquist 2.8 kHz)
    base = flow(system, orbit.t0, orbit.q0, orbit.v0, T, jacobian=False, output_dt=T / samples).result
    lam, V = np.linalg.eig(orbit.monodromy)
    k = int(np.argmax(np.abs(lam)))
    dx = orbit.directions @ np.real(V[:, k]) if orbit.directions.shape[1] == lam.size else np.real(V[:, k])
    x0 = np.concatenate([orbit.q0, orbit.v0])
    dx *= kick * np.abs(x0[:system.n]).max() / np.abs(dx[:system.n]).max()
    n = system.n
    stop = None
    try:
        run = flow(system, orbit.t0, orbit.q0 + dx[:n], orbit.v0 + dx[n:], periods * T, jacobian=False,
                   output_dt=T / samples).result
    except Exception as exc:   # the exact method's refusal (e.g. the shaft would roll on the ring): reported
        stop, run = f"{type(exc).__name__}: {exc}".splitlines()[0], None
    if run is None:
        return {"speed_hz": speed_hz, "stop": stop, "wall_s": time.perf_counter() - t}
    m = samples * (min(run.q.shape[1], samples * periods) // samples)
    c = float(rub_i.system(speed_hz).rings[0].clearance)
    dev = rub_i.disk @ (run.q[:, :m] - np.tile(base.q[:, :samples], m // samples))
    z = dev[0] + 1j * dev[1]
    env = np.abs(z).reshape(-1, samples).max(axis=1)
    linear = np.flatnonzero(env < 1e-2 * c)
    linear = linear[: np.argmax(np.diff(linear) > 1) + 1] if np.any(np.diff(linear) > 1) else linear
    per = np.arange(env.size) * T
    fit = linear[linear.size // 4:]
    rate = float(np.polyfit(per[fit], np.log(env[fit]), 1)[0])
    seg = z[: samples * (linear[-1] + 1)]
    spec = np.abs(np.fft.fft(seg * np.hanning(seg.size)))
    freq = np.fft.fftfreq(seg.size, T / samples)
    j = int(np.argmax(spec))
    radius = np.hypot(*(rub_i.disk @ run.q[:, max(0, m - 10 * samples):m]))
    # the state it goes to: the disk's whole motion over the last 100 periods (or half the run)
    tail = min(100, m // samples // 2) * samples
    u = rub_i.disk @ run.q[:, m - tail:m]
    zt = u[0] + 1j * u[1]
    rt = np.abs(zt)
    spec_t = np.abs(np.fft.fft((zt - zt.mean()) * np.hanning(tail)))
    freq_t = np.fft.fftfreq(tail, T / samples)
    spec_t[np.abs(freq_t - speed_hz) < 2.0] = 0.0                 # the synchronous line (the unbalance)
    jt = int(np.argmax(spec_t))
    r_all = np.hypot(*(rub_i.disk @ run.q[:, :m])).reshape(-1, samples)
    out = {"speed_hz": speed_hz, "mu": mu, "facets": facets, "periods_run": m // samples, "stop": stop,
           "largest_modulus": float(mods.max()), "orbit_rate_per_s": float(np.log(mods.max()) / T),
           "reference_rate_per_s": ref["lam"].real, "transient_rate_per_s": rate,
           "linear_periods": int(linear.size), "whirl_hz": float(freq[j]),
           "resolution_hz": float(speed_hz * samples / seg.size),
           "reference_backward_hz": -ref["backward_hz"], "reference_forward_hz": ref["forward_hz"],
           "reference_backward_share": ref["backward_share"],
           "last10_radius_min_c": float(radius.min() / c), "last10_radius_max_c": float(radius.max() / c),
           "events": int(len(run.events)) if hasattr(run, "events") else None,
           "end_whirl_hz": float(freq_t[jt]), "end_contact_share": float(np.mean(rt > c)),
           "end_ring_force_max_N": float(rub_i.stiffness * max(0.0, rt.max() - c)),
           "end_periods": tail // samples,
           "radius_per_period_c": {"min": (r_all.min(axis=1) / c).tolist(), "max": (r_all.max(axis=1) / c).tolist()},
           "wall_s": time.perf_counter() - t}
    say(f"  transient: {out['periods_run']} periods, linear phase {linear.size} periods, growth {rate:+.4f} 1/s, "
        f"whirl {freq[j]:+.2f} Hz (+- {out['resolution_hz']:.2f}; round ring {-ref['backward_hz']:+.2f} Hz backward "
        f"{ref['backward_share']:.2f}, {ref['forward_hz']:+.2f} forward); last 10 periods: disk radius "
        f"{out['last10_radius_min_c']:.4f}..{out['last10_radius_max_c']:.4f} c; the last {tail // samples} periods: "
        f"non-synchronous whirl {freq_t[jt]:+.2f} Hz, in contact {out['end_contact_share']:.0%} of the time, ring "
        f"force up to {out['end_ring_force_max_N']:.1f} N [{out['wall_s']:.0f} s]")
    return out


def orbit_rates(stiffness: float, mu: float, facets: int, speeds, say) -> list[dict]:
    """The polygon orbit's largest multiplier at each speed (single shootings): ln|mu| / T against the round ring's
    largest real part."""
    rub_r, rub_i = ElasticRub(stiffness, mu, facets), ElasticRub(stiffness, mu, facets, "inertial")
    out = []
    for f in speeds:
        orbit, ref = exact_orbit(rub_r, rub_i, f)
        k = int(np.argmax(np.abs(orbit.multipliers)))
        out.append({"speed_hz": float(f), "facets": facets, "converged": bool(orbit.converged),
                    "stable": bool(orbit.stable), "rate_per_s": float(np.log(abs(orbit.multipliers[k])) * f),
                    "reference_rate_per_s": ref["lam"].real, "radius_c": ref["radius"] / 1e-4,
                    "events_per_period": int(orbit.events_per_period)})
        say(f"  {facets} facets, {f:g} Hz: ln|mu|/T {out[-1]['rate_per_s']:+.4f} 1/s (round ring "
            f"{ref['lam'].real:+.4f}), stable {orbit.stable}")
    return out


def branch(stiffness: float, mu: float, facets: int, lo: float, hi: float, steps: int, say) -> dict:
    """The exact flow's orbit branch over speed (:func:`nsfem.periodic.branch.orbit_branch`, inertial frame) from
    the round ring's state at lo: its located bifurcations (one piece: it stops where the section meets a corner)."""
    from nsfem.periodic.branch import orbit_branch

    rub_r, rub_i = ElasticRub(stiffness, mu, facets), ElasticRub(stiffness, mu, facets, "inertial")
    t = time.perf_counter()
    t0, q, v = inertial_section(rub_i, reduced_reference(rub_r, lo))
    br = orbit_branch(rub_i.system, lambda f: 1.0 / f, q, v, lo, hi, key="rotation.speed_hz", t0=t0,
                      max_steps=steps, switch=False,
                      on_point=lambda bp, m: say(f"  branch {bp.p:.6g} Hz: max |multiplier| "
                                                 f"{np.abs(bp.multipliers).max():.6f}"))
    pts = [{"speed_hz": p["rotation.speed_hz"], "stable": p["stable"],
            "max_modulus": float(max(abs(complex(*m)) for m in p["multipliers"]))} for p in br.points]
    return {"mu": mu, "facets": facets, "points": pts,
            "bifurcations": [{"kind": b["kind"], "value": b["value"]} for b in br.bifurcations],
            "stop": br.stop, "reason": br.reason, "wall_s": time.perf_counter() - t}


def resonance_panel(ax, rates: list[dict], exact: list[dict], runs: list[dict], mu: float) -> None:
    """The resonance curve through the onset: the synchronous rub's disk radius on the exact flow (64-gon) against
    speed, solid where its orbit is stable, dashed where unstable, the located Neimark-Sacker point, and the range
    of radii the transient past the onset ends in (the backward whirl, partly off the ring)."""
    pts = sorted((r for r in rates if r.get("radius_c") is not None and r.get("converged", True)),
                 key=lambda r: r["speed_hz"])
    s = np.array([r["speed_hz"] for r in pts], dtype=float)
    rad = np.array([r["radius_c"] for r in pts], dtype=float)
    ok = np.array([r["rate_per_s"] < 0 for r in pts], dtype=bool)
    onset = next((e for e in exact if e["facets"] == 64 and e["mu"] == mu), None)
    for keep, style, label in ((ok, "-", "synchronous rub, stable"), (~ok, "--", "synchronous rub, unstable")):
        idx = np.flatnonzero(keep)
        if idx.size:   # each part drawn up to the onset, where it meets the other
            lo, hi = idx[0], idx[-1]
            xs, ys = list(s[lo:hi + 1]), list(rad[lo:hi + 1])
            if onset is not None:   # (s has points here)
                r_on = float(np.interp(onset["onset_hz"], s, rad))
                xs, ys = (xs + [onset["onset_hz"]], ys + [r_on]) if keep is ok else ([onset["onset_hz"]] + xs,
                                                                                   [r_on] + ys)
            ax.plot(xs, ys, style, color="C0", label=label)
            ax.plot(s[idx], rad[idx], ".", color="C0", ms=5)
    if onset is not None and s.size:
        ax.plot(onset["onset_hz"], float(np.interp(onset["onset_hz"], s, rad)), "D", color="C3", ms=7,
                label=f"Neimark-Sacker {onset['onset_hz']:.4f} Hz (exact flow)")
    for run in runs:
        if run.get("last10_radius_min_c") is not None:
            ax.vlines(run["speed_hz"], run["last10_radius_min_c"], run["last10_radius_max_c"], color="C3", lw=3,
                      alpha=0.6, label=f"transient's end at {run['speed_hz']:g} Hz: backward whirl "
                                       f"{run['end_whirl_hz']:+.1f} Hz (radius range)")
    ax.axhline(1.0, color="grey", lw=0.5)
    top = max([1.2, *rad, *(r.get("last10_radius_max_c") or 0.0 for r in runs)])
    ax.set_ylim(top=1.0 + 1.8 * (top - 1.0))   # room above the data for the legend
    ax.set_xlabel("speed [Hz]")
    ax.set_ylabel("disk radius / clearance")
    ax.set_title(f"mu = {mu:g}, 64-gon: resonance curve through the onset", fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="upper left")
    else:
        ax.text(0.5, 0.5, "no exact-flow orbits (--quick)", transform=ax.transAxes, ha="center", fontsize=8)


def figure(curve: list[dict], onsets: list[dict], rates: list[dict], exact: list[dict], runs: list[dict],
           mu: float, path: Path, mu_start: float | None = None) -> None:
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax4, ax3) = plt.subplots(1, 4, figsize=(20, 4.6))
    cf = [c for c in curve if c["closed_hz"] is not None]
    ax1.plot([c["closed_hz"] for c in cf], [c["mu"] for c in cf], "-", color="C0",
             label="closed form (Jeffcott, Routh-Hurwitz D3 = 0)")
    red = [o for o in onsets if o["reduced_hz"] is not None]
    ax1.plot([o["reduced_hz"] for o in red], [o["mu"] for o in red], "s", mfc="none", color="C1",
             label="reduced model, round ring")
    labelled = set()
    for e in exact:
        ax1.plot(e["onset_hz"], e["mu"], "kx" if e["facets"] == 64 else "k+", ms=9,
                 label=None if e["facets"] in labelled else f"exact flow, {e['facets']}-gon (inertial frame)")
        labelled.add(e["facets"])
    ax1.axvline(curve[0]["rub_start_hz"], color="grey", ls=":", lw=0.8)
    if mu_start is not None:
        ax1.axhline(mu_start, color="C0", ls="--", lw=0.8)
        ax1.text(26.0, mu_start - 1.3e-3, f"unstable from the rub's start: mu > {mu_start:.4f}", fontsize=7,
                 color="C0")
    ax1.text(curve[0]["rub_start_hz"] + 0.2, 0.02, "rub begins", fontsize=7, color="grey", rotation=90,
             transform=ax1.get_xaxis_transform())
    ax1.set_ylim(0.015, 0.043)
    ax1.set_xlabel("speed [Hz]")
    ax1.set_ylabel("friction mu")
    ax1.set_title("k_s = 2e6 N/m: the synchronous rub is unstable right of the line", fontsize=9)
    ax1.legend(fontsize=7, loc="center right")
    r64 = [r for r in rates if r["facets"] == 64]
    f = np.array([r["reference_rate_per_s"] for r in r64])
    s = np.array([r["speed_hz"] for r in r64])
    ax2.plot(s, f, "-", color="C1", label="round ring: max Re lambda (reduced model)")
    ax2.plot(s, [r["rate_per_s"] for r in r64], "k.", ms=7, label="exact flow, 64-gon: ln|multiplier| / T")
    for run in runs:
        if run.get("transient_rate_per_s") is not None:
            ax2.plot(run["speed_hz"], run["transient_rate_per_s"], "r^", ms=7,
                     label=f"transient at {run['speed_hz']:g} Hz: whirl {run['whirl_hz']:+.1f} Hz "
                           f"({'backward' if run['whirl_hz'] < 0 else 'forward'})")
    ax2.axhline(0.0, color="grey", lw=0.5)
    ax2.set_xlabel("speed [Hz]")
    ax2.set_ylabel("growth rate [1/s]")
    ax2.set_title(f"mu = {mu:g}: stable below 0, a backward whirl grows above", fontsize=9)
    ax2.legend(fontsize=7)
    resonance_panel(ax4, r64, exact, runs, mu)
    for run in runs:
        env = run.get("radius_per_period_c")
        if env:
            t = np.arange(len(env["min"])) / run["speed_hz"]
            ax3.fill_between(t, env["min"], env["max"], color="C3", alpha=0.5, lw=0,
                             label=f"{run['speed_hz']:g} Hz, 64-gon: min..max per period")
            ax3.axhline(1.0, color="grey", lw=0.5)
            ax3.set_title(f"transient at {run['speed_hz']:g} Hz from the orbit: ends whirling "
                          f"{run['end_whirl_hz']:+.1f} Hz", fontsize=9)
    ax3.set_xlabel("time [s]")
    ax3.set_ylabel("disk radius / clearance")
    if ax3.get_legend_handles_labels()[0]:
        ax3.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="closed form and reduced model only")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--stiffness", type=float, default=2e6, help="the ring's mount k_s [N/m]")
    ap.add_argument("--mu", type=float, default=0.03, help="the friction of the exact-flow checks")
    ap.add_argument("--facets", type=int, nargs="*", default=[64, 128])
    ap.add_argument("--transient-hz", type=float, default=24.0)
    ap.add_argument("--periods", type=int, default=300)
    ap.add_argument("--steps", type=int, default=20, help="the branch's continuation steps")
    ap.add_argument("--replot", action="store_true", help="redraw the figure from the saved JSON only")
    a = ap.parse_args(argv)
    if a.replot:
        d = json.loads((OUT / "rub_backward_whirl.json").read_text())
        figure(d["curve"], d["onsets"], d["rates"], d["exact_onsets"], d["transients"], d["mu"], FIGURE,
               d.get("mu_at_rub_start"))
        return 0
    if not (math.isfinite(a.stiffness) and 1e5 <= a.stiffness <= 1e8):
        ap.error(f"--stiffness must be a mount stiffness in [1e5, 1e8] N/m, got {a.stiffness!r}")
    if not (math.isfinite(a.mu) and 0.0 < a.mu <= 1.0):
        ap.error(f"--mu must be a friction coefficient in (0, 1], got {a.mu!r}")
    if any(F < 8 for F in a.facets) or a.periods < 8 or a.steps < 1:
        ap.error("--facets must be at least 8, --periods at least 8, --steps at least 1")
    if not (math.isfinite(a.transient_hz) and 16.0 <= a.transient_hz <= 40.0):
        ap.error(f"--transient-hz must be a speed in [16, 40] Hz, got {a.transient_hz!r}")
    say = (lambda s: print(s, file=sys.stderr)) if a.json else print
    t = time.perf_counter()
    jeff = modal_jeffcott(ElasticRub(a.stiffness, a.mu))
    start = rub_start(jeff)
    say(f"modal Jeffcott: m {jeff.m:.4f} kg, k {jeff.k:.6g} N/m, c_e {jeff.c_e:g}, c_i {jeff.c_i:.4g} N s/m; "
        f"rub from {start:.4f} Hz")
    mu_start = friction_at_rub_start(jeff, start)
    say(f"closed form: unstable from the rub's beginning for mu > {mu_start:.5f}")
    if not a.quick:   # the exact flow's checks need an onset at --mu, and the transient a speed past it
        on = reduced_onset(ElasticRub(a.stiffness, a.mu), start + 1e-3, 40.0)
        if on is None or on["speed_hz"] < start + 1.0 or on["speed_hz"] > 39.0:
            ap.error(f"--mu {a.mu:g}: the reduced model's rub on this ring has no onset between {start + 1.0:.2f} and "
                     f"39 Hz (the closed form: unstable from the rub's start above mu = {mu_start:.4f}); the exact "
                     "flow's checks need one: pick a smaller mu, or use --quick")
        ref_on = on["speed_hz"]
        if a.transient_hz <= ref_on:
            ap.error(f"--transient-hz {a.transient_hz:g} must lie past the onset, {ref_on:.3f} Hz at mu {a.mu:g}")
    curve = []
    for mu in np.round(np.linspace(0.016, 0.04, 49), 6):
        jeff.mu = float(mu)
        on = jeffcott_onset(jeff, start + 1e-3, 40.0)
        curve.append({"mu": float(mu), "rub_start_hz": start, "closed_hz": None if on is None else on["speed_hz"]})
    onsets = []
    for mu in (0.02, 0.025, 0.03, 0.035):
        jeff.mu = mu
        closed = jeffcott_onset(jeff, start + 1e-3, 40.0)
        reduced = reduced_onset(ElasticRub(a.stiffness, mu), start + 1e-3, 40.0)
        onsets.append({"mu": mu, "closed_hz": closed and closed["speed_hz"],
                       "reduced_hz": reduced and reduced["speed_hz"],
                       "closed": closed, "reduced": reduced})
        say(f"mu {mu:g}: onset closed form {closed and round(closed['speed_hz'], 4)} Hz (backward "
            f"{closed and round(closed['backward_hz'], 3)} Hz, share {closed and round(closed['backward_share'], 3)}), "
            f"reduced model {reduced and round(reduced['speed_hz'], 4)} Hz (backward "
            f"{reduced and round(reduced['backward_hz'], 3)} Hz, "
            f"share {reduced and round(reduced['backward_share'], 3)})")
    rates, exact, runs, branches = [], [], [], []
    if not a.quick:
        grid = np.arange(round(ref_on) - 4.0, round(ref_on) + 6.0)
        rates = orbit_rates(a.stiffness, a.mu, 64, [float(f) for f in grid if start + 0.5 < f <= 40.0], say)
        for F in a.facets:
            say(f"onset on the exact flow: {F} facets")
            exact.append(exact_onset(a.stiffness, a.mu, F, ref_on - 1.0, ref_on + 1.0, say))
            say(f"  {exact[-1]['onset_hz']:.5f} Hz ({exact[-1]['onset_hz'] - ref_on:+.5f} Hz from the round ring)")
        for mu in (0.02, 0.025, 0.035):   # the map's other frictions on the 64-gon
            if mu == a.mu:
                continue
            on = next(o["reduced_hz"] for o in onsets if o["mu"] == mu)
            if on is None or on < start + 1.0 or on > 39.0:
                continue
            say(f"onset on the exact flow: 64 facets, mu {mu:g}")
            exact.append(exact_onset(a.stiffness, mu, 64, on - 1.0, on + 1.0, say))
            say(f"  {exact[-1]['onset_hz']:.5f} Hz ({exact[-1]['onset_hz'] - on:+.5f} Hz from the round ring)")
        say(f"branch: 64 facets, {ref_on - 0.5:.2f}..{ref_on + 0.5:.2f} Hz")
        branches.append(branch(a.stiffness, a.mu, 64, round(ref_on - 0.5, 2), round(ref_on + 0.5, 2), a.steps, say))
        say(f"  bifurcations {branches[-1]['bifurcations']}, stop {branches[-1]['stop']} "
            f"({branches[-1]['wall_s']:.0f} s)")
        say(f"transient: 64 facets, {a.transient_hz:g} Hz, {a.periods} periods")
        runs.append(transient(a.stiffness, a.mu, 64, a.transient_hz, a.periods, say, kick=1e-3))
    payload = {"stiffness": a.stiffness, "mu": a.mu, "jeffcott": vars(jeff), "mu_at_rub_start": mu_start,
               "curve": curve, "onsets": onsets,
               "rates": rates, "exact_onsets": exact, "branches": branches, "transients": runs,
               "machine": machine(), "wall_s": time.perf_counter() - t}
    name = "rub_backward_whirl_quick" if a.quick else "rub_backward_whirl"
    write_outputs(OUT, name, curve, json.loads(json.dumps(payload, default=float)))
    figure(curve, onsets, rates, exact, runs, a.mu, OUT / f"{name}.png" if a.quick else FIGURE, mu_start)
    if a.json:
        print(json.dumps(payload, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
