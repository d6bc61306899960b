"""The harmonically forced impact oscillator in closed form: an independent reference for nsfem.periodic.

One degree of freedom against a rigid stop with Newton restitution (the set-up of Shaw & Holmes 1983,
J. Sound Vib. 90, 129-155; Peterka 1974; grazing after Nordmark 1991, J. Sound Vib. 145, 279-297)::

    m x'' + c x' + k x = F cos(w t),   gap g = d - x >= 0,   at g = 0 with x' > 0:  x'+ = -e x'-

Plain NumPy/SciPy; nothing here imports nsfem. State y = (x, x'), T = 2 pi / w.

Flight. y(t) = p(t) + E(t - s) (y(s) - p(s)): p the harmonic steady state (A cos wt + B sin wt,
A = F (k - m w^2) / D, B = F c w / D, D = (k - m w^2)^2 + (c w)^2) and E(s) = exp(L s), L = [[0, 1], [-k/m, -c/m]],
in closed form by Cayley-Hamilton: E(s) = e^{mu s} (cosh(r s) I + sinh(r s) / r (L - mu I)), mu = -c / 2m,
r^2 = mu^2 - k/m (complex r for an underdamped oscillator; the result is real).

Period-1 orbit, one impact per period at t = tau (phase phi = w tau) with approach velocity u = x'(tau-) > 0
(the gap's rate g' = -u < 0 before the impact).
Leaving the stop at (d, -e u) and arriving after T at (d, u), with p(tau + T) = p(tau):
(I - E(T)) (d e1 - p(tau)) + u b = 0, b = e2 + e E(T) e2. Eliminating u (the cross product with b) leaves
beta . (cos phi, sin phi) = alpha, alpha and beta fixed by (I - E)^T (b2, -b1): two phases
phi = theta +- arccos(alpha / |beta|) (no root-find), then u = -(a . b) / |b|^2. A root is an orbit when u > 0
and the flight stays off the stop: the gap over (tau, tau + T) is sampled on 2048 points and each interior
local minimum refined by Brent's bounded minimization (the smallest interior minimum, ``gap_min``, must be > 0;
the gap is 0 at both ends, rising after the impact and falling before the next, so a crossing makes one < 0).
At alpha = +-|beta| the two roots merge: the fold (saddle-node) of Shaw & Holmes.

Saltation matrix (derived). The impact surface h(y) = x - d, normal n = (1, 0); the jump R(y) = (x, -e x')
with R_y = diag(1, -e); the fields before/after f- = (u, a-), f+ = (-e u, a+), a+- = (F cos phi - c x'+- - k d) / m.
A perturbation dy before the surface reaches it dtau = -n.dy / n.f- later; mapping through R and flowing back
with f+ gives S = R_y + (f+ - R_y f-) n^T / (n . f-):
    S = [[-e, 0], [(a+ + e a-) / u, -e]],   a+ + e a- = (1 + e)(F cos phi - k d) / m   (the c terms cancel).
The monodromy at the section t = 0 (0 < tau < T) is M = E(T - tau) S E(tau); its eigenvalues (the Floquet
multipliers) are those of S E(T), det M = e^2 e^{-c T / m}. A multiplier through -1 (1 + tr M + det M = 0) is the
period doubling. Grazing (u -> 0, the harmonic steady state just touching the stop: its amplitude = d) makes
S_21 ~ 1 / u blow up (the square-root singularity of Nordmark's discontinuity map, seen at the fixed point whose
u vanishes linearly in w_g - w): mu_1 ~ S_21 E_12(T), the impacting orbit is unstable next to grazing
(unless E_12(T) = 0).

Period-2 orbit (two impacts per 2T, at tau1 and tau2 = tau1 + T1, T2 = 2T - T1): the four conditions
(d, u2) = p(tau2) + E(T1) ((d, -e u1) - p(tau1)), (d, u1) = p(tau1) + E(T2) ((d, -e u2) - p(tau2)) solved by
scipy's fsolve (Powell's hybrid Newton) from the period-1 orbit with split flight times and velocities;
multipliers of S2 E(T1) S1 E(T2). (Not closed form: a reference only as good as its residual, which is returned.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, fsolve, minimize_scalar

#: samples of one flight for the gap's sign (each interior local minimum is then refined by Brent's method)
GAP_SAMPLES = 2048


@dataclass(frozen=True)
class Oscillator:
    """m x'' + c x' + k x = F cos(w t) with a rigid stop at x = d (gap d - x) and restitution e."""

    m: float = 1.0
    c: float = 0.1
    k: float = 1.0
    F: float = 1.0
    d: float = 0.0
    e: float = 0.8

    def __post_init__(self):
        for name in ("m", "c", "k", "F", "d", "e"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"impact oscillator: {name} must be finite, got {getattr(self, name)}")
        if self.m <= 0 or self.k <= 0 or self.c < 0:
            raise ValueError(f"impact oscillator: needs m > 0, k > 0, c >= 0, got m={self.m}, k={self.k}, c={self.c}")
        if not 0.0 < self.e <= 1.0:
            raise ValueError(f"impact oscillator: restitution e must lie in (0, 1], got {self.e}")

    @property
    def L(self) -> np.ndarray:
        """The state matrix of (x, x')."""
        return np.array([[0.0, 1.0], [-self.k / self.m, -self.c / self.m]])


def check_frequency(w: float) -> float:
    if not (math.isfinite(w) and w > 0):
        raise ValueError(f"impact oscillator: the forcing frequency w must be finite and > 0, got {w}")
    return float(w)


def transition(osc: Oscillator, s) -> np.ndarray:
    """E(s) = exp(L s) in closed form (Cayley-Hamilton), shape s.shape + (2, 2)."""
    s = np.asarray(s, dtype=float)
    mu = -osc.c / (2.0 * osc.m)
    r = np.sqrt(complex(mu * mu - osc.k / osc.m))
    rs = r * s
    ch = np.cosh(rs).real
    sh = np.where(np.abs(rs) < 1e-8, s, (np.sinh(rs) / (r if r != 0 else 1.0)).real)
    decay = np.exp(mu * s)[..., None, None]
    return decay * (ch[..., None, None] * np.eye(2) + sh[..., None, None] * (osc.L - mu * np.eye(2)))


def harmonic(osc: Oscillator, w: float, t) -> np.ndarray:
    """The harmonic steady state p(t) = (x, x'), shape t.shape + (2,)."""
    A, B = harmonic_coefficients(osc, w)
    t = np.asarray(t, dtype=float)
    cw, sw = np.cos(w * t), np.sin(w * t)
    return np.stack([A * cw + B * sw, w * (B * cw - A * sw)], axis=-1)


def harmonic_coefficients(osc: Oscillator, w: float) -> tuple[float, float]:
    """(A, B) of x_p = A cos wt + B sin wt."""
    D = (osc.k - osc.m * w * w) ** 2 + (osc.c * w) ** 2
    return osc.F * (osc.k - osc.m * w * w) / D, osc.F * osc.c * w / D


def flight(osc: Oscillator, w: float, t_start: float, y_start, s) -> np.ndarray:
    """The free flight from state y_start at t_start, at the delays s (array): shape s.shape + (2,)."""
    s = np.asarray(s, dtype=float)
    y0 = np.asarray(y_start, dtype=float) - harmonic(osc, w, t_start)
    return harmonic(osc, w, t_start + s) + transition(osc, s) @ y0


def saltation(osc: Oscillator, phi: float, u: float) -> np.ndarray:
    """S of an impact at phase phi with approach velocity u > 0 (module docstring)."""
    s21 = (1.0 + osc.e) * (osc.F * math.cos(phi) - osc.k * osc.d) / (osc.m * u)
    return np.array([[-osc.e, 0.0], [s21, -osc.e]])


@dataclass(frozen=True)
class Period1:
    """A root of the period-1 conditions (an orbit when ``exists``)."""

    w: float
    branch: int          # +1 or -1: the sign before arccos in phi = theta +- arccos(alpha / |beta|)
    phi: float           # impact phase w tau in [0, 2 pi)
    tau: float           # impact time in [0, T); at tau = 0 (x0, v0) is the state just before the impact
    u: float             # approach velocity x'(tau-) [m/s]; > 0 for an orbit
    gap_min: float       # smallest gap over the open flight (tau, tau + T) [m]; > 0 for an orbit
    x0: float            # the state at the section t = 0 (mod T)
    v0: float
    monodromy: np.ndarray   # (2, 2) at the section t = 0
    multipliers: np.ndarray  # complex (2,), largest modulus first

    @property
    def exists(self) -> bool:
        return self.u > 0.0 and self.gap_min > 0.0

    @property
    def period(self) -> float:
        return 2.0 * math.pi / self.w


def period1_roots(osc: Oscillator, w: float) -> list[Period1]:
    """Both roots of the period-1 one-impact conditions at w (empty past the fold: |alpha| > |beta|)."""
    w = check_frequency(w)
    T = 2.0 * math.pi / w
    E = transition(osc, T)
    A, B = harmonic_coefficients(osc, w)
    P = np.array([[A, B], [w * B, -w * A]])          # p(tau) = P (cos phi, sin phi)
    b = np.array([osc.e * E[0, 1], 1.0 + osc.e * E[1, 1]])
    rvec = (np.eye(2) - E).T @ np.array([b[1], -b[0]])
    # cross(a, b) = rvec . (d e1 - P c(phi)) = 0  <=>  (rvec P) . c(phi) = d rvec_1
    alpha, beta = osc.d * rvec[0], rvec @ P
    if not np.any(beta):                             # F = 0: no forcing, no periodic impact motion
        return []
    ratio = alpha / float(np.hypot(*beta))
    if abs(ratio) > 1.0:
        return []
    theta, spread = math.atan2(beta[1], beta[0]), math.acos(ratio)
    roots = []
    for branch in (+1, -1):
        phi = (theta + branch * spread) % (2.0 * math.pi)
        tau = phi / w
        a = (np.eye(2) - E) @ (np.array([osc.d, 0.0]) - P @ np.array([math.cos(phi), math.sin(phi)]))
        u = float(-(a @ b) / (b @ b))
        roots.append(_complete(osc, w, branch, phi, tau, u))
    return roots


def _complete(osc: Oscillator, w: float, branch: int, phi: float, tau: float, u: float) -> Period1:
    T = 2.0 * math.pi / w
    start = np.array([osc.d, -osc.e * u])
    gap_min = flight_gap_min(osc, w, tau, start, T)
    y0 = flight(osc, w, tau, start, T - tau)                  # t = T = 0 (mod T), after the flight from tau
    if u > 0:
        S = saltation(osc, phi, u)
        M = transition(osc, T - tau) @ S @ transition(osc, tau)
        mult = np.linalg.eigvals(M).astype(complex)
        mult = mult[np.argsort(-np.abs(mult), kind="stable")]
    else:
        M, mult = np.full((2, 2), np.nan), np.full(2, np.nan + 0j)
    return Period1(w, branch, phi, tau, u, gap_min, float(y0[0]), float(y0[1]), M, mult)


def flight_gap_min(osc: Oscillator, w: float, t_start: float, y_start, duration: float) -> float:
    """The smallest interior local minimum of the gap d - x over a flight from the stop to the stop
    (t_start, t_start + duration): grid, then Brent's bounded search around each grid minimum; inf when the gap
    only rises and falls. The gap leaves and reaches 0 at the ends, so a flight through the stop has such a
    minimum < 0; a dip between two samples lies in the bracket of the smaller of them."""
    s = np.linspace(0.0, duration, GAP_SAMPLES + 1)
    g = osc.d - flight(osc, w, t_start, y_start, s)[:, 0]
    inner = np.flatnonzero((g[1:-1] <= g[:-2]) & (g[1:-1] <= g[2:])) + 1
    best = math.inf
    for i in inner:
        res = minimize_scalar(lambda z: osc.d - flight(osc, w, t_start, y_start, z)[0], bounds=(s[i - 1], s[i + 1]),
                              method="bounded", options={"xatol": 1e-14 * duration})
        best = min(best, float(res.fun))
    return best


def period1_orbits(osc: Oscillator, w: float) -> list[Period1]:
    """The period-1 one-impact orbits at w (the roots with u > 0 whose flight stays off the stop)."""
    return [r for r in period1_roots(osc, w) if r.exists]


def period1_branch(osc: Oscillator, w: float, branch: int) -> Period1:
    """The root of the given branch (+1 or -1) at w; ValueError past the fold."""
    roots = [r for r in period1_roots(osc, w) if r.branch == branch]
    if not roots:
        raise ValueError(f"impact oscillator: no period-1 root at w = {w} (past the fold)")
    return roots[0]


def flip_function(osc: Oscillator, w: float, branch: int) -> float:
    """1 + tr M + det M = (1 + mu_1)(1 + mu_2): zero when a multiplier passes -1."""
    M = period1_branch(osc, w, branch).monodromy
    return 1.0 + float(np.trace(M)) + float(np.linalg.det(M))


def period_doubling_frequency(osc: Oscillator, w_lo: float, w_hi: float, branch: int = -1) -> float:
    """The forcing frequency in [w_lo, w_hi] where the period-1 orbit of ``branch`` has a multiplier at -1
    (Brent's method on :func:`flip_function`, which must change sign over the bracket, to 1e-13 relative)."""
    f_lo, f_hi = flip_function(osc, w_lo, branch), flip_function(osc, w_hi, branch)
    if f_lo * f_hi > 0:
        raise ValueError(f"impact oscillator: no multiplier crosses -1 between w = {w_lo} and {w_hi} "
                         f"((1 + mu1)(1 + mu2) = {f_lo:.3g} and {f_hi:.3g})")
    w = brentq(lambda z: flip_function(osc, z, branch), w_lo, w_hi, xtol=1e-15, rtol=1e-13)
    if not period1_branch(osc, w, branch).exists:
        raise ValueError(f"impact oscillator: the period-1 root at w = {w} is no orbit (u <= 0 or the flight "
                         "crosses the stop)")
    return float(w)


def grazing_frequencies(osc: Oscillator) -> np.ndarray:
    """The forcing frequencies where the harmonic steady state just touches the stop, its amplitude
    F / sqrt((k - m w^2)^2 + (c w)^2) = d > 0: the roots w^2 of m^2 w^4 + (c^2 - 2 k m) w^2 + k^2 - (F/d)^2 = 0
    (ascending; empty for d <= 0, where the harmonic motion around x = 0 always reaches the stop)."""
    if osc.d <= 0:
        return np.zeros(0)
    roots = np.roots([osc.m ** 2, osc.c ** 2 - 2.0 * osc.k * osc.m, osc.k ** 2 - (osc.F / osc.d) ** 2])
    w2 = np.sort(roots[(np.abs(roots.imag) <= 1e-12 * np.abs(roots)) & (roots.real > 0)].real)
    return np.sqrt(w2)


def harmonic_gap_min(osc: Oscillator, w: float) -> float:
    """The smallest gap of the harmonic steady state (no impact): d - amplitude."""
    A, B = harmonic_coefficients(osc, check_frequency(w))
    return osc.d - math.hypot(A, B)


@dataclass(frozen=True)
class Period2:
    """A period-2 orbit with two impacts per 2T (at tau1 < tau2 in [0, 2T), approach velocities u1, u2)."""

    w: float
    tau: np.ndarray          # (2,)
    u: np.ndarray            # (2,)
    gap_min: float           # smallest interior local minimum of the gap over both flights
    x0: float                # state at the section t = 0 (mod 2T)
    v0: float
    monodromy: np.ndarray    # (2, 2) over 2T at the section t = 0
    multipliers: np.ndarray  # complex (2,), largest modulus first
    residual: float          # of the four orbit conditions after Newton

    @property
    def exists(self) -> bool:
        return bool(np.all(self.u > 0) and self.gap_min > 0)


def _period2_conditions(osc: Oscillator, w: float, z: np.ndarray) -> np.ndarray:
    tau1, T1, u1, u2 = z
    T2 = 4.0 * math.pi / w - T1
    tau2 = tau1 + T1
    d = osc.d
    end1 = flight(osc, w, tau1, [d, -osc.e * u1], T1)
    end2 = flight(osc, w, tau2, [d, -osc.e * u2], T2)
    return np.array([end1[0] - d, end1[1] - u2, end2[0] - d, end2[1] - u1])


def period2_orbit(osc: Oscillator, w: float, guess=None) -> Period2:
    """The period-2 orbit at w by Newton (scipy's fsolve) on the four impact conditions (module docstring) from
    ``guess`` = (tau1, T1, u1, u2), or by default from each period-1 orbit at w with the flight times split
    into T (1 +- s) and the velocities into u (1 +- 0.2), s = 0.05, 0.1, 0.2: the first start that converges
    (conditions to 1e-12 of the velocity scale) off the period-1 orbit (|T1 - T| > 1e-6 T); ValueError if none."""
    w = check_frequency(w)
    T = 2.0 * math.pi / w
    if guess is None:
        starts = [[p1.tau, T * (1 + dT), p1.u * (1 + du), p1.u * (1 - du)] for p1 in period1_orbits(osc, w)
                  for dT in (-0.05, 0.05, -0.1, 0.1, -0.2, 0.2) for du in (0.2, -0.2)]
    else:
        starts = [guess]
    scale = max(abs(osc.F) / osc.k * w, 1e-300)
    for start in starts:
        z = fsolve(lambda q: _period2_conditions(osc, w, q), np.asarray(start, float), xtol=1e-13)
        if (np.abs(_period2_conditions(osc, w, z)).max() <= 1e-12 * scale
                and (guess is not None or abs(z[1] - T) > 1e-6 * T)):
            break
    else:
        raise ValueError(f"impact oscillator: Newton found no period-2 orbit at w = {w} from {len(starts)} start(s)"
                         + ("" if starts else " (no period-1 orbit to start from)"))
    residual = float(np.abs(_period2_conditions(osc, w, z)).max())
    tau1, T1, u1, u2 = (float(v) for v in z)
    T2 = 2.0 * T - T1
    g = min(flight_gap_min(osc, w, tau1, [osc.d, -osc.e * u1], T1) if T1 > 0 else -math.inf,
            flight_gap_min(osc, w, tau1 + T1, [osc.d, -osc.e * u2], T2) if T2 > 0 else -math.inf)
    # the impacts in [0, 2T), in time order; the section t = 0 = 2T (mod 2T) lies after the later one
    (ta, ua), (tb, ub) = sorted([(tau1 % (2.0 * T), u1), ((tau1 + T1) % (2.0 * T), u2)])
    y0 = flight(osc, w, tb, [osc.d, -osc.e * ub], 2.0 * T - tb)
    if min(ua, ub) > 0:
        M = (transition(osc, 2.0 * T - tb) @ saltation(osc, w * tb, ub) @ transition(osc, tb - ta)
             @ saltation(osc, w * ta, ua) @ transition(osc, ta))
        mult = np.linalg.eigvals(M).astype(complex)
        mult = mult[np.argsort(-np.abs(mult), kind="stable")]
    else:
        M, mult = np.full((2, 2), np.nan), np.full(2, np.nan + 0j)
    return Period2(w, np.array([ta, tb]), np.array([ua, ub]), g, float(y0[0]), float(y0[1]), M, mult, residual)


def orbit_state(osc: Oscillator, w: float, impacts, period: float, t) -> np.ndarray:
    """The state (x, x') at the times t (array) of a periodic orbit with the given impacts [(tau, u), ...]
    in [0, period): the flight from the last impact before t (mod period). Shape t.shape + (2,)."""
    t = np.asarray(t, dtype=float)
    taus = np.array([tau for tau, _ in impacts])
    us = np.array([u for _, u in impacts])
    order = np.argsort(taus)
    taus, us = taus[order], us[order]
    phase = np.mod(t, period)
    last = np.searchsorted(taus, phase, side="right") - 1      # -1: before the first impact, the last one's flight
    tau = np.where(last >= 0, taus[last], taus[-1] - period)
    u = us[last]                                              # us[-1] for last == -1
    start = np.stack([np.full_like(u, osc.d), -osc.e * u], axis=-1)
    y = np.empty(t.shape + (2,))
    for i in np.ndindex(t.shape):
        y[i] = flight(osc, w, tau[i], start[i], phase[i] - tau[i])
    return y
