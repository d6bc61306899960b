"""The breathing crack (issue 19): open-crack frequencies, free breathing vibration, 2x/3x through speed, detection.

Four parts, each against an independent reference:

(a) Open crack = a beam with a rotational spring. The characteristic equation of a two-span Euler-Bernoulli
    beam (w = A cos bx + B sin bx + C cosh bx + D sinh bx per span; at the crack w, w'', w''' continuous and
    w'_right - w'_left = c EI w'') is an 8 x 8 determinant, whose roots brentq brackets on a fine grid;
    against nsfem's FE frequencies (natural_frequencies, contact "open") of pinned-pinned and cantilever
    bars, rectangle and circle, both bending planes (each with its own compliance), depths 0.1-0.6 (circles to 0.5).
(b) A non-rotating pinned-pinned bar with a breathing crack at mid-span (faces are contacts, restitution 0,
    no gravity), set vibrating in its first mode: the period of the mid-span deflection (zero crossings)
    against the bilinear frequency 2 f_open f_closed / (f_open + f_closed) of a one-mode model.
(c) A weight-dominated cracked shaft (circular, pinned-pinned, crack at mid-span, gravity, no unbalance,
    Rayleigh damping alpha M) at steady speeds: the 1x, 2x and 3x harmonics of an inertial vertical probe
    over whole revolutions after the transient, nsfem ``exact`` (faces decide when they touch) against a
    Gasch switching crack written here: the same FE model and rotating-frame operators, the hinge closed
    (intact) while the static gravity moment puts the crack's side in compression and open (the hinge's
    spring condensed statically into the stiffness) while it puts it in tension, integrated by solve_ivp.
(d) Crack depth against the 2x amplitude at a fixed speed below the 2x resonance (the detection curve),
    both models.

    python studies/crack.py [--quick] [--json] [--out DIR]

Writes crack.csv/.json and crack_*.png into studies/out/crack and copies the figures to docs/figures.
--quick: fewer depths, speeds and revolutions (15-35 s); the full study 2-4 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from study_io import machine, write_outputs

import nsfem
from nsfem.analysis.modes import contact_basis, natural_frequencies
from nsfem.fem.crack import MAX_CIRCLE_DEPTH
from nsfem.fem.constraints import dense
from nsfem.fem.rotating import rotor_operators
from nsfem.integrate import ContactSystem, integrate
from nsfem.reduce import scene_reduction
from nsfem.sensors import read
from nsfem.system import linear_system

ROOT = Path(__file__).resolve().parents[1]
E, RHO = 2.1e11, 7850.0
TMP = Path(tempfile.mkdtemp(prefix="nsfem-crack-"))


def scene_of(text: str, overrides=()):
    """A scene from TOML text (written to a scratch file)."""
    path = TMP / f"s{abs(hash(text))}.toml"
    path.write_text(text)
    return nsfem.load_scene(str(path), list(overrides))


def bar_toml(section: str, supports: str, x: float, depth: float, elements: int, extra: str = "") -> str:
    geom = ('section = "rectangle"\nwidth = 0.02\nheight = 0.01' if section == "rectangle" else
            'section = "circle"\ndiameter = 0.02')
    return f"""
[shaft]
length = 1.0
{geom}
E = {E}
rho = {RHO}
supports = "{supports}"
[[crack]]
x = {x}
depth = {depth}
[rotation]
gravity = 0.0
[mesh]
elements = {elements}
[reduction]
method = "none"
{extra}
"""


# ---------------------------------------------------------------- (a) beam with a rotational spring

def _rows(bx: float) -> np.ndarray:
    """w, w'/b, w''/b^2, w'''/b^3 of (cos, sin, cosh, sinh)(b x): rows 0..3."""
    c, s, ch, sh = math.cos(bx), math.sin(bx), math.cosh(bx), math.sinh(bx)
    return np.array([[c, s, ch, sh], [-s, c, sh, ch], [-c, -s, ch, sh], [s, -c, sh, ch]])


#: which of the rows w, w', w'', w''' an end holds at zero
END_ROWS = {"pinned": (0, 2), "clamped": (0, 1), "free": (2, 3)}


def spring_beam_det(b: float, L: float, a: float, kappa: float, ends: tuple[str, str]) -> float:
    """Determinant of the two-span beam's boundary and crack conditions at wavenumber b [1/m]; kappa = c EI [m]."""
    A = np.zeros((8, 8))
    left, mid1, mid2, right = _rows(0.0), _rows(b * a), _rows(0.0), _rows(b * (L - a))
    A[0:2, 0:4] = left[list(END_ROWS[ends[0]])]
    A[2:4, 4:8] = right[list(END_ROWS[ends[1]])]
    for r, k in enumerate((0, 2, 3)):            # w, w'', w''' continuous
        A[4 + r, 0:4], A[4 + r, 4:8] = mid1[k], -mid2[k]
    # w'_2 - w'_1 = c EI w''_1, scaled by 1/b: rows1 - rows1' ... with w'' = b^2 row 2
    A[7, 0:4] = -mid1[1] - kappa * b * mid1[2]
    A[7, 4:8] = mid2[1]
    return float(np.linalg.det(A))


def spring_beam_frequencies(L, a, EI, m, c, ends, count) -> list[float]:
    """The lowest ``count`` natural frequencies [Hz] of the beam with a rotational spring of compliance c at a."""
    f = functools.partial(spring_beam_det, L=L, a=a, kappa=c * EI, ends=ends)
    grid = np.linspace(0.2, 4.0 * (count + 1), 40 * (count + 1)) / L
    vals = [f(b) for b in grid]
    roots = []
    for b0, b1, v0, v1 in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
        if v0 == 0.0 or v0 * v1 < 0:
            roots.append(brentq(f, b0, b1, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200))
        if len(roots) == count:
            break
    return [b * b * math.sqrt(EI / m) / (2 * math.pi) for b in roots]


SUPPORT_ENDS = {"pinned-pinned": ("pinned", "pinned"), "clamped-free": ("clamped", "free")}


def part_a(depths, elements, count=4, x=0.3) -> list[dict]:
    rows = []
    for supports, ends in SUPPORT_ENDS.items():
        for section in ("rectangle", "circle"):
            for depth in depths:
                if section == "circle" and depth > MAX_CIRCLE_DEPTH:
                    continue   # beyond a = R the strip integration of the compliance has no meaning
                scene = scene_of(bar_toml(section, supports, x, depth, elements))
                model = nsfem.fem.build_model(scene)
                crack = model.stack.cracks[0]
                seg = model.stack.segments[0]
                modes = natural_frequencies(model, "open", 2 * count + 4)
                fe = {"V": [], "W": []}
                for f, fld in zip(modes.frequencies_hz, modes.fields):
                    if fld in fe:
                        fe[fld].append(float(f))
                # bending in y (V) uses the inertia about z, in z (W) the one about y
                if section == "rectangle":
                    inertia = {"V": seg.height * seg.width ** 3 / 12, "W": seg.width * seg.height ** 3 / 12}
                    area = seg.width * seg.height
                else:
                    inertia = {"V": math.pi * seg.width ** 4 / 64, "W": math.pi * seg.width ** 4 / 64}
                    area = math.pi * seg.width ** 2 / 4
                for fld, c in zip(("V", "W"), crack.compliance):
                    exact = spring_beam_frequencies(1.0, x, E * inertia[fld], RHO * area, c, ends, count)
                    for k, (fx, ff) in enumerate(zip(exact, fe[fld][:count])):
                        h = 1.0 / elements
                        bh = math.sqrt(2 * math.pi * fx / math.sqrt(E * inertia[fld] / (RHO * area))) * h
                        rows.append({"part": "a", "supports": supports, "section": section, "depth": depth,
                                     "plane": fld, "mode": k + 1, "compliance": c, "f_exact_hz": fx, "f_fe_hz": ff,
                                     "rel_error": ff / fx - 1, "expected_h4": bh ** 4 / 1440})
    return rows


# ---------------------------------------------------------------- (b) free breathing vibration

def upward_crossings(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Times where s crosses zero upwards (linear interpolation)."""
    k = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
    return t[k] - s[k] * (t[k + 1] - t[k]) / (s[k + 1] - s[k])


def part_b(depths, cycles, elements=40, modes=16) -> list[dict]:
    """Pinned-pinned rectangular bar (soft in z), crack at mid-span from -z, started with the closed first
    z-mode's velocity downwards (the crack opens first). Piecewise linear and positively homogeneous: the
    period does not depend on the amplitude."""
    rows = []
    for depth in depths:
        extra = '[[sensor]]\nname = "mid_z"\nx = 0.5\ndirection = "+z"\nframe = "inertial"\n'
        scene = scene_of(bar_toml("rectangle", "pinned-pinned", 0.5, depth, elements, extra),
                         [f"reduction.method=craig-bampton", f"reduction.modes={modes}"])
        model = nsfem.fem.build_model(scene)
        red = scene_reduction(scene.reduction, model)
        system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
        f = {}
        for state in ("open", "closed"):
            m = natural_frequencies(model, state, 6)
            f[state] = next(float(v) for v, fld in zip(m.frequencies_hz, m.fields) if fld == "W")
        f_bl = 2 * f["open"] * f["closed"] / (f["open"] + f["closed"])
        # the closed structure's first z-mode in the reduced coordinates
        N = sla.null_space(system.contacts.JN.T)
        lam, X = sla.eigh(N.T @ system.Q @ N, N.T @ system.M @ N)
        W_row = read(scene.sensors, model, dense(red.T), np.zeros(len(lam)), N @ X, "rotating", 0.0)[:, 0]
        k = next(i for i in range(len(lam)) if abs(W_row[i]) > 1e-3 * np.abs(W_row).max())
        v0 = -N @ X[:, k] / W_row[k] * 1e-3 * 2 * math.pi * f["closed"]      # 1 mm amplitude, downwards
        t_end = cycles / f_bl
        t0 = time.perf_counter()
        res = integrate(system, t_end, "exact", min(2e-5, 0.002 / f_bl), np.zeros(system.n), v0)
        wall = time.perf_counter() - t0
        s = read(scene.sensors, model, dense(red.T), res.t, res.q, "rotating", 0.0)[:, 0]
        up = upward_crossings(res.t, s)
        periods = np.diff(up)
        f_meas = 1.0 / periods.mean()
        # spectrum peak, refined by a parabola through the log magnitudes
        win = np.hanning(s.size)
        spec = np.abs(np.fft.rfft((s - s.mean()) * win, 8 * s.size))
        freqs = np.fft.rfftfreq(8 * s.size, res.t[1] - res.t[0])
        j = 1 + int(np.argmax(spec[1:]))
        y0, y1, y2 = np.log(spec[j - 1:j + 2])
        f_peak = freqs[j] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (freqs[1] - freqs[0])
        gap = res.gap.min(axis=0)
        open_frac = float(np.mean(gap > 1e-12 * np.abs(res.gap).max()))
        amp = np.abs(s)
        rows.append({"part": "b", "depth": depth, "f_open_hz": f["open"], "f_closed_hz": f["closed"],
                     "f_bilinear_hz": f_bl, "f_measured_hz": f_meas, "f_spectrum_hz": float(f_peak),
                     "measured_over_bilinear": f_meas / f_bl - 1,
                     "period_spread": float(periods.std() / periods.mean()),
                     "measured_over_closed": f_meas / f["closed"] - 1, "open_fraction": open_frac,
                     "cycles": len(periods), "impacts": len(res.impacts), "events": len(res.events),
                     "amplitude_decay": float(amp[res.t > res.t[-1] - 1 / f_bl].max() / amp[res.t < 1 / f_bl].max()),
                     "energy_lost_in_impacts_J": res.energy.get("lost_in_impacts_J"), "wall_s": wall,
                     "t": res.t.tolist() if depth == depths[-1] else None,
                     "s": s.tolist() if depth == depths[-1] else None})
    return rows


# ---------------------------------------------------------------- (c), (d) the cracked shaft through speed

ROTOR = """
title = "weight-dominated cracked shaft"
[shaft]
length = 1.0
section = "circle"
diameter = 0.025
E = {E}
rho = {RHO}
supports = "pinned-pinned"
[[crack]]
x = 0.5
depth = {depth}
side = "-z"
restitution = 0.0
[[sensor]]
name = "mid_z"
x = 0.5
direction = "+z"
frame = "inertial"
[[sensor]]
name = "mid_y"
x = 0.5
direction = "+y"
frame = "inertial"
[rotation]
frame = "rotating"
speed_hz = {speed}
gravity = 9.81
[damping]
rayleigh = [{alpha}, 0.0]
[mesh]
elements = {elements}
[reduction]
method = "craig-bampton"
modes = {modes}
"""
#: Rayleigh alpha [1/s]: 2 % of critical damping on the first mode (50.7 Hz)
ALPHA = 12.0


def rotor_scene(depth: float, speed_hz: float, elements: int = 40, modes: int = 16):
    return scene_of(ROTOR.format(E=E, RHO=RHO, depth=depth, speed=speed_hz, alpha=ALPHA, elements=elements,
                                 modes=modes))


def harmonic_steady_state(M, C, Q, fc, fs, w):
    """(a, b) of the periodic response a cos wt + b sin wt of M q'' + C q' + Q q = fc cos wt + fs sin wt."""
    K = Q - w * w * M
    A = np.block([[K, w * C], [-w * C, K]])
    ab = np.linalg.solve(A, np.concatenate([fc, fs]))
    return ab[:M.shape[0]], ab[M.shape[0]:]


def harmonics(t: np.ndarray, s: np.ndarray, w: float, orders=(1, 2, 3)) -> dict[int, float]:
    """Amplitudes of the k-th harmonics of w over the samples (whole revolutions, uniform, endpoint excluded)."""
    return {k: float(2 * abs(np.mean(s * np.exp(-1j * k * w * t)))) for k in orders}


def run_nsfem(depth: float, speed_hz: float, revs: int, last: int, per_rev: int = 64) -> dict:
    """nsfem exact from the intact rotor's steady state; harmonics of the inertial probes over the last revolutions."""
    scene = rotor_scene(depth, speed_hz)
    model = nsfem.fem.build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    w = system.omega
    N = sla.null_space(system.contacts.JN.T)
    P = lambda A: N.T @ A @ N  # noqa: E731
    fc, fs = (np.zeros(system.n) if v is None else v for v in (system.fc, system.fs))
    a, b = harmonic_steady_state(P(system.M), P(system.C), P(system.Q), N.T @ fc, N.T @ fs, w)
    q0, v0 = N @ a, N @ (w * b)
    if np.any(system.f0):
        q0 = q0 + N @ np.linalg.solve(P(system.Q), N.T @ system.f0)
    t_end = revs / speed_hz
    t0 = time.perf_counter()
    res = integrate(system, t_end, "exact", 1.0 / (speed_hz * per_rev), q0, v0)
    wall = time.perf_counter() - t0
    s = read(scene.sensors, model, dense(red.T), res.t, res.q, "rotating", speed_hz)
    keep = slice(res.t.size - 1 - last * per_rev, res.t.size - 1)
    t, z, y = res.t[keep], s[keep, 0], s[keep, 1]
    h = harmonics(t, z, w)
    gap = res.gap[:, keep].mean(axis=0)
    return {"harm": h, "mean_z": float(z.mean()), "harm_y": harmonics(t, y, w), "wall_s": wall,
            "open_fraction": float(np.mean(gap > 1e-9 * np.abs(res.gap).max())), "impacts": len(res.impacts),
            "events": len(res.events), "t": t, "z": z}


#: the Gasch reference's modes above this frequency [Hz] get 2 % modal damping (see Gasch.__init__)
HIGH_HZ = 1000.0


class Gasch:
    """The prescribed (Gasch) switching crack on the same FE model and rotating-frame operators.

    Coordinates: r, the closed (intact) structure's (contact_basis "closed"), and d, the right side's slopes
    V', W' at the crack (the hinge's relative rotation): together they span the open model. Closed: d = 0.
    Open: d condensed statically (the hinge has no inertia of its own in this reference; its slope dofs'
    share of the elements' mass is dropped), K_open = Q_rr - Q_rd Q_dd^-1 Q_dr, the same M_rr and C_rr. Both
    are projected on the closed rotor's lowest ``modes`` modes plus the two static shapes Q_rr^-1 Q_rd of the
    hinge moments (exact for the static open deflection). The state is continuous through a switch (K(t)
    switches, as in Gasch's model); the switch follows the sign of the crack's opening under the static
    gravity load of the open model at the frame's angle: open for the half revolution the crack's side is
    in tension."""

    def __init__(self, depth: float, speed_hz: float, modes: int = 6, method: str = "DOP853", rtol: float = 1e-6,
                 atol: float = 1e-8):
        self.method, self.rtol, self.atol = method, rtol, atol
        scene = rotor_scene(depth, speed_hz)
        model = nsfem.fem.build_model(scene)
        crack = model.stack.cracks[0]
        Tc = dense(contact_basis(model, "closed"))
        nr = Tc.shape[1]
        D = np.zeros((model.n_full, 2))
        for j, name in enumerate(("V'", "W'")):
            D[model.dof(crack.segments[1], name, crack.x), j] = 1.0
        B = np.hstack([Tc, D])
        ops = rotor_operators(model, B)
        ls = linear_system(ops, speed_hz, scene.rotation.gravity, scene.rotation.phase_deg, (ALPHA, 0.0))
        M, C, Q = dense(ls.M), dense(ls.C), dense(ls.Q)
        f = [np.zeros(nr + 2) if v is None else np.asarray(v) for v in (ls.f0, ls.fc, ls.fs)]
        r, d = slice(0, nr), slice(nr, nr + 2)
        Kdd_inv_Kdr = np.linalg.solve(Q[d, d], Q[d, r])
        K_open = Q[r, r] - Q[r, d] @ Kdd_inv_Kdr
        f_open = [v[r] - Q[r, d] @ np.linalg.solve(Q[d, d], v[d]) for v in f]
        # basis: the closed rotor's lowest modes and the hinge moments' static shapes (M-orthonormalized)
        _, Phi = sla.eigh(0.5 * (Q[r, r] + Q[r, r].T), M[r, r], subset_by_index=[0, modes - 1])
        P0 = np.hstack([Phi, np.linalg.solve(Q[r, r], Q[r, d])])
        Mp = P0.T @ M[r, r] @ P0
        mu, V = sla.eigh(0.5 * (Mp + Mp.T))
        P = P0 @ (V / np.sqrt(mu))
        Pt = lambda A: P.T @ A @ P  # noqa: E731
        self.M, self.C = Pt(M[r, r]), Pt(C[r, r])
        self.K = {"closed": Pt(Q[r, r]), "open": Pt(K_open)}
        self.f = {"closed": [P.T @ v[r] for v in f], "open": [P.T @ v for v in f_open]}
        # the hinge moments' static shapes bring stiff modes (3.6-9 kHz) that the mass-proportional damping
        # leaves undamped; switching K every half revolution pumps them parametrically (the reference grew
        # without bound at 0.32 and 0.52 of critical). Damp every reduced mode above HIGH_HZ at 2 % of
        # critical (in the closed state's modes): the rotor's response near its first mode is untouched.
        lam, X = sla.eigh(0.5 * (self.K["closed"] + self.K["closed"].T), self.M)
        high = np.sqrt(np.abs(lam)) / (2 * math.pi) > HIGH_HZ
        MX = self.M @ X[:, high]
        self.C = self.C + MX @ np.diag(2 * 0.02 * np.sqrt(np.abs(lam[high]))) @ MX.T
        self.w = ls.omega if ls.omega else 2 * math.pi * speed_hz
        self.basis = B[:, r] @ P
        self.model, self.scene = model, scene
        # the opening of the open model under the static gravity load, summed over the crack's face points
        from nsfem.contact.kinematics import gap_jacobian
        J, _ = gap_jacobian(model)
        g = np.asarray(dense(J).T @ B).sum(axis=0)
        self.opening = [float(g @ np.linalg.solve(Q, v)) for v in f]   # constant, cos, sin parts
        self.n = self.M.shape[0]
        Minv = np.linalg.inv(self.M)
        self.A = {k: np.block([[np.zeros((self.n, self.n)), np.eye(self.n)], [-Minv @ K, -Minv @ self.C]])
                  for k, K in self.K.items()}
        self.F = {k: [np.concatenate([np.zeros(self.n), Minv @ v]) for v in fs] for k, fs in self.f.items()}

    def frequencies(self, state: str) -> np.ndarray:
        """Undamped natural frequencies [Hz] of the reduced model at the speed (rotating frame, no Coriolis)."""
        return np.sqrt(np.abs(sla.eigvalsh(0.5 * (self.K[state] + self.K[state].T), self.M))) / (2 * math.pi)

    def state(self, t: float) -> str:
        g0, gc, gs = self.opening
        return "open" if g0 + gc * math.cos(self.w * t) + gs * math.sin(self.w * t) > 0 else "closed"

    def switches(self, t_end: float) -> np.ndarray:
        """The times in (0, t_end) where the static opening changes sign."""
        g0, gc, gs = self.opening
        fn = lambda t: g0 + gc * math.cos(self.w * t) + gs * math.sin(self.w * t)  # noqa: E731
        grid = np.linspace(0.0, t_end, int(64 * t_end * self.w / (2 * math.pi)) + 2)
        v = np.array([fn(t) for t in grid])
        return np.array([brentq(fn, a, b, xtol=1e-15) for a, b, va, vb in zip(grid[:-1], grid[1:], v[:-1], v[1:])
                         if va * vb < 0])

    def run(self, t_end: float, t_eval: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """States (2 n, len(t_eval)) by solve_ivp (DOP853) piecewise between the prescribed switches."""
        cuts = np.concatenate([[0.0], self.switches(t_end), [t_end]])
        out = np.zeros((2 * self.n, t_eval.size))
        x = x0
        for a, b in zip(cuts[:-1], cuts[1:]):
            st = self.state(0.5 * (a + b))
            A, (F0, Fc, Fs) = self.A[st], self.F[st]
            w = self.w
            rhs = lambda t, y: A @ y + F0 + Fc * math.cos(w * t) + Fs * math.sin(w * t)  # noqa: E731
            inside = (t_eval >= a) & (t_eval < b)
            sol = solve_ivp(rhs, (a, b), x, method=self.method, t_eval=np.append(t_eval[inside], b),
                            rtol=self.rtol, atol=self.atol * np.abs(self.x0).max(), **({"jac": A} if self.method in
                                                                                  ("Radau", "BDF", "LSODA") else {}))
            out[:, inside] = sol.y[:, :-1]
            x = sol.y[:, -1]
        out[:, t_eval >= t_end] = x[:, None]
        return out


def run_gasch(depth: float, speed_hz: float, revs: int, last: int, per_rev: int = 64, model=None) -> dict:
    g = model or Gasch(depth, speed_hz)
    # start from the intact rotor's steady state, as the nsfem run
    a, b = harmonic_steady_state(g.M, g.C, g.K["closed"], g.f["closed"][1], g.f["closed"][2], g.w)
    x0 = np.concatenate([a + (np.linalg.solve(g.K["closed"], g.f["closed"][0]) if np.any(g.f["closed"][0]) else 0),
                         g.w * b])
    t_end = revs / speed_hz
    t_eval = np.arange(revs * per_rev + 1) / (speed_hz * per_rev)
    t0 = time.perf_counter()
    g.x0 = x0
    X = g.run(t_end, t_eval, x0)
    wall = time.perf_counter() - t0
    s = read(g.scene.sensors, g.model, g.basis, t_eval, X[:g.n], "rotating", speed_hz)
    keep = slice(t_eval.size - 1 - last * per_rev, t_eval.size - 1)
    t, z = t_eval[keep], s[keep, 0]
    return {"harm": harmonics(t, z, g.w), "mean_z": float(z.mean()), "harm_y": harmonics(t, s[keep, 1], g.w),
            "wall_s": wall, "t": t, "z": z}


def part_c(ratios, depth, revs, last, f_crit) -> list[dict]:
    rows = []
    for ratio in ratios:
        speed = ratio * f_crit
        ns, ga = run_nsfem(depth, speed, revs, last), run_gasch(depth, speed, revs, last)
        rows.append({"part": "c", "depth": depth, "speed_ratio": ratio, "speed_hz": speed,
                     **{f"nsfem_{k}x_m": v for k, v in ns["harm"].items()},
                     **{f"gasch_{k}x_m": v for k, v in ga["harm"].items()},
                     "nsfem_mean_z_m": ns["mean_z"], "gasch_mean_z_m": ga["mean_z"],
                     "nsfem_open_fraction": ns["open_fraction"], "nsfem_impacts": ns["impacts"],
                     "nsfem_wall_s": ns["wall_s"], "gasch_wall_s": ga["wall_s"],
                     # the switched model can grow without bound (energy pumped at each switch into the hinge's
                     # stiff local shapes, which mass-proportional damping hardly damps): flagged, not compared
                     "gasch_diverged": bool(max(ga["harm"].values()) > abs(ns["mean_z"]))})
    return rows


def _save(fig, axes, path: Path, legend: bool = True) -> Path:
    """Grid (and legends) on every panel, written at 100 dpi, the figure closed."""
    import matplotlib.pyplot as plt

    for a in axes:
        a.grid(alpha=0.3)
        if legend:
            a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot(out: Path, rows_a, rows_b, rows_c, rows_d) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    for (sup, sec), mk in zip([(a, b) for a in SUPPORT_ENDS for b in ("rectangle", "circle")], "osD^"):
        mine = [r for r in rows_a if r["supports"] == sup and r["section"] == sec]
        ax[0].semilogy([r["depth"] + 0.004 * r["mode"] for r in mine], [abs(r["rel_error"]) for r in mine], mk,
                       mfc="none", label=f"{sup}, {sec}")
        ax[1].plot([r["depth"] for r in mine if r["mode"] == 1 and r["plane"] == "W"],
                   [r["f_exact_hz"] for r in mine if r["mode"] == 1 and r["plane"] == "W"], mk + "-", label=f"{sup}, {sec}")
    ax[0].set(xlabel="depth (points offset by mode)", ylabel="|f_FE / f_exact - 1|", title="(a) open crack vs spring beam")
    ax[1].set(xlabel="depth a/h, a/D", ylabel="first frequency, opening plane [Hz]", title="(a) closed form")
    paths.append(_save(fig, ax, out / "crack_frequencies.png"))

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    last = rows_b[-1]
    ax[0].plot(np.asarray(last["t"]) * 1e3, np.asarray(last["s"]) * 1e3, lw=0.8)
    ax[0].set(xlabel="t [ms]", ylabel="mid-span W [mm]", title=f"(b) breathing bar, depth {last['depth']:g}")
    ax[1].plot([r["depth"] for r in rows_b], [r["measured_over_bilinear"] for r in rows_b], "o-", label="measured / bilinear - 1")
    ax[1].plot([r["depth"] for r in rows_b], [r["measured_over_closed"] for r in rows_b], "s--", label="measured / closed - 1")
    ax[1].set(xlabel="depth a/h", ylabel="relative", title="(b) breathing frequency")
    ax[1].legend(fontsize=8)
    paths.append(_save(fig, ax, out / "crack_breathing.png", legend=False))

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    x = [r["speed_ratio"] for r in rows_c]
    for k, c in zip((1, 2, 3), ("C0", "C1", "C2")):
        ax[0].semilogy(x, [r[f"nsfem_{k}x_m"] for r in rows_c], "o-", color=c, label=f"{k}x nsfem (faces as contacts)")
        ax[0].semilogy(x, [np.nan if r["gasch_diverged"] else r[f"gasch_{k}x_m"] for r in rows_c], "x--", color=c, label=f"{k}x Gasch (prescribed)")
    for v in (1 / 3, 1 / 2):
        ax[0].axvline(v, color="k", lw=0.5)
    ax[0].set(xlabel="speed / first critical speed (intact)", ylabel="amplitude, inertial vertical probe [m]",
              title="(c) harmonics through speed")
    d = [r["depth"] for r in rows_d]
    ax[1].plot(d, [r["nsfem_2x_m"] * 1e6 for r in rows_d], "o-", label="nsfem")
    ax[1].plot(d, [r["gasch_2x_m"] * 1e6 for r in rows_d], "x--", label="Gasch")
    ax[1].set(xlabel="depth a/D", ylabel="2x amplitude [um]", title=f"(d) detection curve at {rows_d[0]['speed_ratio']:g} critical")
    paths.append(_save(fig, ax, out / "crack_speed.png"))
    return paths


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer depths, speeds and revolutions")
    ap.add_argument("--json", action="store_true", help="print the JSON object")
    ap.add_argument("--out", default="studies/out/crack")
    args = ap.parse_args(argv)
    say = functools.partial(print, file=sys.stderr) if args.json else print
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    q = args.quick
    t0 = time.perf_counter()
    walls = {}

    tp = time.perf_counter()
    elements_a = 40 if q else 80
    rows_a = part_a([0.2, 0.6] if q else [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], elements_a)
    walls["a"] = time.perf_counter() - tp
    say(f"(a) open crack against the spring beam's characteristic equation, {elements_a} elements:")
    say(f"{'supports':>14} {'section':>9} {'depth':>5} {'plane':>5} {'mode':>4} {'f_exact Hz':>12} {'f_FE/f_ex-1':>12} {'(bh)^4/1440':>12}")
    for r in rows_a:
        say(f"{r['supports']:>14} {r['section']:>9} {r['depth']:5.1f} {r['plane']:>5} {r['mode']:4d} {r['f_exact_hz']:12.5f} "
            f"{r['rel_error']:12.3e} {r['expected_h4']:12.3e}")
    resid = max(abs(r["rel_error"] - r["expected_h4"]) for r in rows_a)
    say(f"max |f_FE/f_exact - 1| = {max(abs(r['rel_error']) for r in rows_a):.3e}; after the Hermite error (bh)^4/1440: {resid:.2e}")

    tp = time.perf_counter()
    rows_b = part_b([0.2, 0.6] if q else [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], 10 if q else 40)
    walls["b"] = time.perf_counter() - tp
    say("(b) free breathing vibration (pinned-pinned bar, crack at mid-span, restitution 0):")
    say(f"{'depth':>5} {'f_open':>9} {'f_closed':>9} {'f_bilin':>10} {'f_meas':>10} {'meas/bil-1':>11} {'meas/clo-1':>11} {'open frac':>9} {'impacts':>7}")
    for r in rows_b:
        say(f"{r['depth']:5.1f} {r['f_open_hz']:9.4f} {r['f_closed_hz']:9.4f} {r['f_bilinear_hz']:10.5f} {r['f_measured_hz']:10.5f} "
            f"{r['measured_over_bilinear']:11.2e} {r['measured_over_closed']:11.2e} {r['open_fraction']:9.4f} {r['impacts']:7d}")

    f_crit = float(natural_frequencies(nsfem.fem.build_model(rotor_scene(0.4, 0.0)), "closed", 1).frequencies_hz[0])
    revs, last = (24, 8) if q else (40, 10)
    ratios = [1 / 3, 0.5] if q else [0.25, 0.3, 0.32, 1 / 3, 0.35, 0.4, 0.45, 0.48, 0.5, 0.52, 0.55, 0.6]
    tp = time.perf_counter()
    rows_c = part_c(ratios, 0.4, revs, last, f_crit)
    walls["c"] = time.perf_counter() - tp
    say(f"(c) weight-dominated shaft, crack a/D = 0.4 at mid-span, critical speed (intact) {f_crit:.4f} Hz, "
        f"{revs} revolutions, harmonics over the last {last}:")
    say(f"{'speed/crit':>10} {'1x nsfem':>10} {'1x Gasch':>10} {'2x nsfem':>10} {'2x Gasch':>10} {'3x nsfem':>10} {'3x Gasch':>10} {'open frac':>9} {'impacts':>7}")
    for r in rows_c:
        say(f"{r['speed_ratio']:10.4f} {r['nsfem_1x_m']:10.3e} {r['gasch_1x_m']:10.3e} {r['nsfem_2x_m']:10.3e} {r['gasch_2x_m']:10.3e} "
            f"{r['nsfem_3x_m']:10.3e} {r['gasch_3x_m']:10.3e} {r['nsfem_open_fraction']:9.3f} {r['nsfem_impacts']:7d}"
            + ("  (Gasch diverged)" if r["gasch_diverged"] else ""))
    ratio_d = 0.45
    tp = time.perf_counter()
    rows_d = []
    for depth in ([0.2, 0.4] if q else [0.1, 0.2, 0.3, 0.4, 0.5]):   # a circle: up to a/D = 0.5
        rows_d += [dict(r, part="d") for r in part_c([ratio_d], depth, revs, last, f_crit)]
    walls["d"] = time.perf_counter() - tp
    say(f"(d) detection: 2x amplitude against depth at {ratio_d} of the critical speed:")
    for r in rows_d:
        say(f"  depth {r['depth']:.1f}: 2x nsfem {r['nsfem_2x_m']:.3e} m, Gasch {r['gasch_2x_m']:.3e} m "
            f"(static sag {abs(r['nsfem_mean_z_m']):.3e} m)")
    wall = time.perf_counter() - t0
    figs = plot(out, rows_a, rows_b, rows_c, rows_d)
    for f in figs:
        docs_fig = ROOT / "docs" / "figures" / f.name
        if not q or not docs_fig.exists():
            shutil.copyfile(f, docs_fig)
    strip = lambda r: {k: v for k, v in r.items() if k not in ("t", "s")}  # noqa: E731
    rows = [strip(r) for r in rows_a + rows_b + rows_c + rows_d]
    ok = [r for r in rows_c if not r["gasch_diverged"]]
    peak = lambda key: max(ok if key.startswith("gasch") else rows_c, key=lambda r: r[key])["speed_ratio"]  # noqa: E731
    payload = {"quick": q, "wall_s": wall, "walls_s": walls, "critical_speed_hz": f_crit,
               "a": {"elements": elements_a, "max_rel_error": max(abs(r["rel_error"]) for r in rows_a),
                     "max_residual_after_h4": resid},
               "b": [strip(r) for r in rows_b], "c": rows_c, "d": rows_d,
               "c_peaks": {"nsfem_2x": peak("nsfem_2x_m"), "gasch_2x": peak("gasch_2x_m"),
                           "nsfem_3x": peak("nsfem_3x_m"), "gasch_3x": peak("gasch_3x_m")},
               "machine": machine()}
    write_outputs(out, "crack", rows, payload)
    say(f"done in {wall:.1f} s ({', '.join(f'{k} {v:.1f} s' for k, v in walls.items())}); wrote {out}/crack.csv, .json, "
        + ", ".join(str(f) for f in figs))
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
