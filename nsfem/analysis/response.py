"""Steady unbalance response of a linear rotor by a harmonic solve per speed (``nsfem response``).

At speed Omega the scene's linear system (:func:`nsfem.system.linear_system`, either frame) is
M q'' + C q' + Q q = f0 + fc cos(Omega t) + fs sin(Omega t). Its steady state is

    q(t) = X0 + Re(X1 e^{i Omega t}),   Q X0 = f0,   (Q + i Omega C - Omega^2 M) X1 = fc - i fs.

A sensor reads v, w at its x. In the scene's frame its 1x is Re(Z e^{i Omega t}) with Z = r X1. In the
other frame the reading is turned by theta = Omega t + phi: the harmonic X1 goes to 0x and 2x, the
static X0 to 1x (the unbalance in the rotating frame is a static load; seen from the casing it whirls
at 1x): with u0 = v0 + i w0, Z_v = u0 e^{i phi}, Z_w = -i u0 e^{i phi} (rotating -> inertial) or
Z_v = conj(u0) e^{i phi}, Z_w = i conj(u0) e^{i phi} (inertial -> rotating).

The amplitude is |Z| and the phase lag phi - arg Z [deg, 0-360): the signal is A cos(theta - lag), the
convention of the sweep's ``phase_<sensor>_deg`` (:mod:`.harmonic`), so a sweep's fitted steady harmonic
equals this solve.

Peaks (API 684's half-power method): a local maximum of a sensor's amplitude A_c at N_c (a parabola
through the three samples around it) whose amplitude falls below A_c / sqrt(2) on both sides within the
speeds, N_1 and N_2 the crossings (linear interpolation between samples); the amplification factor is
N_c / (N_2 - N_1), the separation margin 100 |N_c - N_run| / N_run [%] from the scene's speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import NsfemError


#: Peaks below this share of the largest amplitude of any probe are round-off (eps times the dynamic
#: stiffness's condition, 1e-16 x 1e6-1e7): a probe orthogonal to the response (a z probe of a model whose
#: kept modes move along y only) has wiggles of 1e-20 m beside 5e-5 m, not resonances.
NOISE = 1e-9
#: Dense factorizations up to this many dofs (a reduced model), sparse LU beyond (a full model)
DENSE_LIMIT = 400


@dataclass(frozen=True)
class Response:
    """Per speed [Hz] and sensor: amplitude [m], phase lag [deg], and the complex 1x Z (x = Re(Z e^{i Omega t}))."""

    speeds_hz: np.ndarray
    names: tuple[str, ...]
    Z: np.ndarray             # (speeds, sensors) complex
    phase0: float             # rotation.phase_deg [rad]

    @property
    def amplitude_m(self) -> np.ndarray:
        return np.abs(self.Z)

    @property
    def phase_deg(self) -> np.ndarray:
        return lag_deg(self.Z, self.phase0)


def lag_deg(Z: np.ndarray, phase0: float = 0.0) -> np.ndarray:
    """Phase lag [deg, 0-360) of Re(Z e^{i Omega t}) behind theta = Omega t + phase0.

    >>> float(lag_deg(np.array(1j)))      # cos(theta + 90 deg) = cos(theta - 270 deg)
    270.0
    """
    return np.mod(np.degrees(phase0 - np.angle(Z)), 360.0)


def check_linear(stack) -> None:
    """Refuse a stack with contacts or cracks: a harmonic solve is the steady state of a linear model only."""
    parts = [f"{len(stack.cracks)} crack(s)"] if stack.cracks else []
    kinds = sorted({c.kind for c in stack.contacts if c.kind != "crack"})
    if kinds:
        parts.insert(0, f"contacts ({', '.join(kinds)})")
    if parts:
        raise NsfemError(f"response: the scene has {' and '.join(parts)}; the harmonic solve holds for linear "
                         "scenes only (use nsfem sweep for a nonlinear rotor's resonance curve)")
    if not stack.unbalances:
        raise NsfemError("response: the scene has no [[unbalance]]: its steady 1x response is zero")


def sensor_rows(sensors, model, basis) -> np.ndarray:
    """(sensors, 2, n): the rows reading v and w at each sensor from reduced coordinates (q_full = basis q)."""
    from ..sensors import hermite_row

    B = basis.toarray() if hasattr(basis, "toarray") else np.asarray(basis)
    return np.array([[np.ravel((hermite_row(model, s.segment, f, s.x) @ B)) for f in ("V", "W")] for s in sensors])


def harmonic_response(ops, sensors, model, speeds_hz, rotation, damping) -> Response:
    """The steady 1x of each sensor at each speed (``ops``: operators in reduced coordinates, ops.basis the
    map to full ones; ``rotation``/``damping``: the scene's ``[rotation]`` and ``[damping]``)."""
    from ..system import linear_system

    speeds = np.asarray(speeds_hz, dtype=float)
    rows = sensor_rows(sensors, model, ops.basis if ops.basis is not None else np.eye(ops.n))
    frame = rotation.frame
    phi = math.radians(rotation.phase_deg)
    other = [s.frame != frame for s in sensors]
    sign = np.array([-1.0 if s.direction[0] == "-" else 1.0 for s in sensors])
    axis = np.array([0 if s.direction[1] == "y" else 1 for s in sensors])
    k = np.arange(len(sensors))
    Z = np.zeros((speeds.size, len(sensors)), dtype=complex)
    dense = ops.n <= DENSE_LIMIT
    M = ops.M.toarray() if dense else ops.M.tocsc()
    for i, f in enumerate(speeds):
        sys_ = linear_system(ops, f, rotation.gravity, rotation.phase_deg, damping.rayleigh, damping.external, frame)
        w = sys_.omega
        Q = sys_.Q.toarray() if dense else sys_.Q.tocsc()
        C = (sys_.C.toarray() if dense else sys_.C.tocsc()) if sys_.C is not None else 0.0 * M
        load = (sys_.fc if sys_.fc is not None else 0.0) - 1j * (sys_.fs if sys_.fs is not None else 0.0)
        load = np.broadcast_to(load, (ops.n,)).astype(complex)
        X1 = _solve(Q + 1j * w * C - w * w * M, load, f, "dynamic") if np.any(load) else np.zeros(ops.n, complex)
        same = rows @ X1                                  # (sensors, 2): Z_v, Z_w in the scene's frame
        z = same[k, axis]
        if any(other) and sys_.f0 is not None and np.any(sys_.f0):
            X0 = _solve(Q, sys_.f0, f, "static")
            u0 = (rows @ X0) @ np.array([1.0, 1j])       # v0 + i w0 per sensor
            if frame == "rotating":                       # turned by +theta to the casing
                zv, zw = u0 * np.exp(1j * phi), -1j * u0 * np.exp(1j * phi)
            else:
                zv, zw = np.conj(u0) * np.exp(1j * phi), 1j * np.conj(u0) * np.exp(1j * phi)
            z = np.where(other, np.where(axis == 0, zv, zw), z)
        elif any(other):
            z = np.where(other, 0.0, z)
        Z[i] = sign * z
    return Response(speeds, tuple(s.name for s in sensors), Z, phi)


def _solve(A, b: np.ndarray, speed_hz: float, what: str) -> np.ndarray:
    """A x = b, A dense or sparse; a singular A (a pivot at round-off) is refused with the speed."""
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla

    try:
        if isinstance(A, np.ndarray):
            lu, piv_index = sla.lu_factor(A, check_finite=False)
            piv = np.abs(np.diag(lu))
            factor = lambda rhs: sla.lu_solve((lu, piv_index), rhs, check_finite=False)  # noqa: E731
        else:
            lu = spla.splu(A.tocsc())
            piv = np.abs(lu.U.diagonal())
            factor = lu.solve
    except (ValueError, RuntimeError, sla.LinAlgError):
        piv, factor = np.zeros(1), None
    if factor is None or not piv.min() > 1e-13 * piv.max():
        raise NsfemError(f"response: the {what} stiffness at {speed_hz:g} Hz is singular (a free rotor, an undamped "
                         "resonance or a divergence speed): no steady state; support or damp the rotor, or move the speeds")
    return factor(b)


def half_power_peaks(speeds_hz: np.ndarray, amplitude: np.ndarray) -> list[dict]:
    """Resonance peaks of one amplitude curve by the half-power method: ``speed_hz`` N_c, ``amplitude_m``,
    ``amplification_factor`` N_c / (N_2 - N_1), ``band_hz`` (N_1, N_2).

    >>> f = np.linspace(0.5, 1.5, 2001)                       # a single dof, force-excited, zeta = 0.05
    >>> a = 1 / np.sqrt((1 - f**2) ** 2 + (0.1 * f) ** 2)
    >>> round(half_power_peaks(f, a)[0]["amplification_factor"], 2)   # 1 / (2 zeta) = 10, less O(zeta^2)
    9.95
    """
    s, a = np.asarray(speeds_hz, dtype=float), np.asarray(amplitude, dtype=float)
    out = []
    for j in range(1, s.size - 1):
        if not (a[j] > a[j - 1] and a[j] >= a[j + 1]):
            continue
        nc, ac = _vertex(s[j - 1:j + 2], a[j - 1:j + 2])
        half = ac / math.sqrt(2.0)
        n1, n2 = _crossing(s, a, j, -1, half, ac), _crossing(s, a, j, +1, half, ac)
        if n1 is None or n2 is None or not n2 > n1:
            continue
        out.append({"speed_hz": nc, "amplitude_m": ac, "amplification_factor": nc / (n2 - n1), "band_hz": [n1, n2]})
    return out


def _vertex(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Vertex of the parabola through three points (the middle one when they are collinear)."""
    c2, c1, c0 = np.polyfit(x - x[1], y, 2)
    if not c2 < 0:
        return float(x[1]), float(y[1])
    dx = float(np.clip(-c1 / (2 * c2), x[0] - x[1], x[2] - x[1]))
    return float(x[1] + dx), float(c0 + c1 * dx + c2 * dx * dx)


def _crossing(s, a, j: int, step: int, half: float, top: float) -> float | None:
    """Where the curve, walked from sample j by ``step``, first falls below ``half`` (linear interpolation);
    None when it leaves the speeds or climbs above ``top`` first (another, higher peak)."""
    i = j
    while 0 <= i + step < s.size:
        nxt = i + step
        if a[nxt] > top:
            return None
        if a[nxt] < half:
            return float(s[i] + (s[nxt] - s[i]) * (a[i] - half) / (a[i] - a[nxt]))
        i = nxt
    return None


def peaks(res: Response, run_speed_hz: float) -> list[dict]:
    """Every sensor's half-power peaks with the separation margin [%] from ``run_speed_hz`` (None at rest)."""
    out = []
    floor = NOISE * float(np.max(res.amplitude_m, initial=0.0))
    for k, name in enumerate(res.names):
        for p in half_power_peaks(res.speeds_hz, res.amplitude_m[:, k]):
            if not p["amplitude_m"] > floor:
                continue                                  # round-off wiggles of a probe the response misses
            margin = 100.0 * abs(p["speed_hz"] - run_speed_hz) / run_speed_hz if run_speed_hz > 0 else None
            out.append({"sensor": name, **p, "separation_margin": margin})
    return out


def orbits(res: Response, sensors) -> list[dict]:
    """Per pair of sensors at one x and frame reading y and z: the 1x orbit's semi-axes [m] per speed,
    the minor one signed (+ forward whirl, - backward)."""
    out = []
    for a, sa in enumerate(sensors):
        for b, sb in enumerate(sensors):
            if not (sa.x == sb.x and sa.frame == sb.frame and sa.segment == sb.segment
                    and sa.direction[1] == "y" and sb.direction[1] == "z"):
                continue
            zv = res.Z[:, a] * (-1 if sa.direction[0] == "-" else 1)
            zw = res.Z[:, b] * (-1 if sb.direction[0] == "-" else 1)
            fwd, bwd = np.abs(zv + 1j * zw) / 2, np.abs(np.conj(zv) + 1j * np.conj(zw)) / 2
            out.append({"sensors": [sa.name, sb.name], "semi_major_m": (fwd + bwd).tolist(),
                        "semi_minor_m": (fwd - bwd).tolist()})
    return out


#: stability of the contact-free structure: the roots looked at per speed (as campbell's default count) and at most
#: this many speeds evaluated (a longer list is sampled evenly and the boundaries refined by bisection)
STABILITY_COUNT = 6
STABILITY_GRID = 201


def unstable_ranges(ops, speeds_hz, rotation, damping) -> tuple[np.ndarray, list[tuple[float, float | None, float]]]:
    """Where the contact-free structure at each speed grows (the largest real part of its state roots, as
    :func:`.campbell.growth_rate`, above round-off): a harmonic solve there is a particular solution, not a steady
    state. Returns (unstable flag per speed, [(from_hz, to_hz or None: to the last speed, largest growth [1/s])]).

    The growth is evaluated at the speeds (at most :data:`STABILITY_GRID` of them, evenly sampled beyond) and each
    change of sign between two of them refined by bisection to 1e-6 of the speed, following the root that grows
    at the unstable end (as :func:`.whirl.instability_onsets`); a speed is unstable when it lies in a range."""
    from ..system import linear_system
    from .campbell import _omega_max, growth_rate, state_eigenvalues

    def roots(f):
        system = linear_system(ops, f, 0.0, 0.0, damping.rayleigh, damping.external, rotation.frame)
        return state_eigenvalues(system, STABILITY_COUNT), _omega_max(system.M, system.Q)

    def growth(f):
        lam, top = roots(f)
        return growth_rate(lam, STABILITY_COUNT, top)

    speeds = np.asarray(speeds_hz, dtype=float)
    grid = speeds if speeds.size <= STABILITY_GRID else speeds[np.unique(
        np.round(np.linspace(0, speeds.size - 1, STABILITY_GRID)).astype(int))]
    g = np.array([growth(f) for f in grid])
    up = g > 0.0

    def boundary(a: float, b: float, b_grows: bool) -> float:
        """The speed between a and b where the root growing at the unstable end crosses Re = 0."""
        lam, _ = roots(b if b_grows else a)
        track = lam[np.argmax(lam.real)]
        while b - a > 1e-6 * b:
            mid = 0.5 * (a + b)
            lam, _ = roots(mid)
            track = lam[np.argmin(np.abs(lam - track))]
            if (track.real > 0.0) == b_grows:
                b = mid
            else:
                a = mid
        return 0.5 * (a + b)

    ranges = []
    start = float(grid[0]) if up[0] else None
    for i in range(1, grid.size):
        if up[i] and not up[i - 1]:
            start = boundary(float(grid[i - 1]), float(grid[i]), True)
        elif up[i - 1] and not up[i]:
            end = boundary(float(grid[i - 1]), float(grid[i]), False)
            ranges.append((start, end, float(np.max(g[(grid >= start) & (grid <= end)], initial=0.0))))
            start = None
    if start is not None:
        ranges.append((start, None, float(np.max(g[grid >= start]))))
    flags = np.zeros(speeds.size, dtype=bool)
    for a, b, _ in ranges:
        flags |= (speeds >= a) & ((speeds < b) if b is not None else True)
    return flags, ranges


def unstable_warning(ranges, first_hz: float) -> str | None:
    """The one warning of :func:`response_report` naming the unstable speed ranges and their growth, or None."""
    if not ranges:
        return None
    parts = []
    for a, b, g in ranges:
        where = f"from {a:.4g} Hz" + (f" to {b:.4g} Hz" if b is not None else " on") + (
            "" if a > first_hz else " (from the first speed: it may start lower)")
        parts.append(f"{where} (growth up to {g:.3g} 1/s, amplitude x e every {1 / g:.3g} s)" if g > 0 else where)
    return ("the contact-free structure is unstable " + "; ".join(parts) + ": free motion grows (internal damping, "
            "cross-coupled bearings or a divergence: campbell's instability onsets), so the harmonic solve there is no steady "
            "state; those speeds are marked 'unstable' and their peaks are no resonances to operate by")


def response_report(scene, model, speeds_hz, reduction) -> dict:
    """Everything ``nsfem response`` prints (checked scene: linear, with sensors and an unbalance)."""
    from ..fem.rotating import rotor_operators

    ops = rotor_operators(model, reduction.T)
    res = harmonic_response(ops, scene.sensors, model, speeds_hz, scene.rotation, scene.damping)
    warnings = []
    top = reduction.info.get("max_frequency_hz")
    if top and float(np.max(speeds_hz)) > 0.5 * top:
        warnings.append(f"speeds above {0.5 * top:.4g} Hz, half the reduced model's highest kept mode "
                        f"({top:.4g} Hz), lie outside its validity: raise reduction.modes")
    unstable, ranges = unstable_ranges(ops, speeds_hz, scene.rotation, scene.damping)
    said = unstable_warning(ranges, float(res.speeds_hz[0]))
    if said:
        warnings.append(said)
    amp, ph = res.amplitude_m, res.phase_deg
    found = peaks(res, scene.rotation.speed_hz)
    for p in found:
        p["unstable"] = any(a <= p["speed_hz"] and (b is None or p["speed_hz"] < b) for a, b, _ in ranges)
    return {
        "frame": scene.rotation.frame, "ndof": ops.n, "ndof_full": model.n,
        "speeds_hz": res.speeds_hz.tolist(),
        "sensors": {n: {"amplitude_m": amp[:, k].tolist(), "phase_deg": ph[:, k].tolist()}
                    for k, n in enumerate(res.names)},
        "peaks": found,
        "orbits": orbits(res, scene.sensors),
        "unstable": unstable.tolist(),
        # the structure is stable at every speed below this one (None: at all the speeds)
        "stable_below_hz": float(ranges[0][0]) if ranges else None,
        "unstable_ranges_hz": [[a, b] for a, b, _ in ranges],
        "warnings": warnings,
        "_response": res,
    }
