"""The inertial frame's rotordynamics: whirl senses, critical speeds, instability onsets
(docs/theory.md, "The inertial frame"; ``nsfem campbell`` of a scene with ``[rotation] frame =
"inertial"``).

Whirl frequencies are the state eigenvalues of :mod:`.campbell` at each speed; a root's eigenvector
says whether its orbits turn with the spin (forward) or against it (backward). Critical speeds are
where the undamped rotor whirls synchronously (a Hermitian pencil, no scan); instability onsets are
where the growth rate turns positive (internal damping, cross-coupled bearings).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..fem.constraints import dense as _dense
from ..fem.rotating import RotorOperators
from ..system import linear_system
from .campbell import (VALID_FRACTION, _omega_max, _oscillating, _pencil, branches_json, campbell, frequencies_of,
                       growth_rate, state_eigenvalues)

if TYPE_CHECKING:
    from ..scene import Damping, Rotation

#: A mode whirls forward (backward) when its orbits turn with (against) the spin by more than this
#: share of its lateral amplitude (a circle: 1; a line: 0); between, it is planar (at rest, or on
#: anisotropic bearings where a mode's orbits are flat ellipses)
WHIRL = 1e-3
#: whirl code of a mode without lateral motion
AXIAL = 2


def whirl_sense(X: np.ndarray, basis, turn: sp.spmatrix) -> np.ndarray:
    """Per column x of X (eigenvectors of roots with Im > 0, ~ e^{i w t}): +1 when its orbits turn from
    +y towards +z (the spin's sense: forward), -1 backward, 0 planar. With J the quarter turn,
    Im(x^H J x) / (x^H x)_lateral is +1 for a forward circle (w = -i v), -1 backward, 0 for a line."""
    xf = np.asarray(basis @ X) if basis is not None else X
    Jx = turn @ xf
    lateral = np.asarray(abs(turn).sum(axis=1)).ravel() > 0
    size = np.einsum("ij,ij->j", np.conj(xf[lateral]), xf[lateral]).real
    total = np.einsum("ij,ij->j", np.conj(xf), xf).real
    ratio = np.einsum("ij,ij->j", np.conj(xf), Jx).imag / np.maximum(size, 1e-300)
    sense = np.where(ratio > WHIRL, 1, np.where(ratio < -WHIRL, -1, 0))
    # no lateral motion beyond round-off (an axial mode): no whirl at all
    return np.where(size > 1e-12 * total, sense, AXIAL)


def critical_speeds(ops: RotorOperators, turn: sp.spmatrix, max_hz: float | None = None,
                    forward_only: bool = False, count: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Inertial frame: (speeds [Hz], whirl) where the undamped rotor whirls synchronously, K0 x =
    Omega^2 (M - i Gp1) x (a Hermitian pencil: Gp1 is real skew), the resonances an unbalance can
    drive. On isotropic bearings (``forward_only``) only forward whirl can be driven (a backward mode
    is orthogonal to every load turning with the shaft); on anisotropic ones the backward crossings
    are resonances too. Axial modes are left out. A bearing's cross coupling (circulatory, ``ops.Kbc``)
    makes the pencil non-Hermitian (its roots grow or decay): then :func:`cross_coupled_critical_speeds`
    (the first ``count`` of them)."""
    if ops.Kbc.nnz and np.any(ops.Kbc.data):
        return cross_coupled_critical_speeds(ops, turn, max_hz, forward_only, count)
    return _hermitian_critical_speeds(ops, turn, max_hz, forward_only)


def _hermitian_critical_speeds(ops: RotorOperators, turn: sp.spmatrix, max_hz: float | None = None,
                               forward_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """:func:`critical_speeds` of the rotor without circulatory stiffness (K0 only)."""
    nu, X, _ = _pencil(_dense(ops.M) - 1j * _dense(ops.Gp1), _dense(ops.K0))
    f = 1.0 / np.sqrt(nu) / (2 * math.pi)
    w = whirl_sense(X, ops.basis, turn)
    keep = (w != AXIAL) & (f <= (math.inf if max_hz is None else max_hz))
    if forward_only:
        # a pair the spin does not split (a disk at midspan, a shaft without disks) is degenerate: the
        # solver returns two planar vectors for its one forward critical speed; keep it once
        keep &= w != -1
        f, w = f[keep], w[keep]
        order = np.argsort(f)
        f, w = f[order], w[order]
        single = np.ones(f.size, dtype=bool)
        single[1:] = ~((w[1:] == 0) & (w[:-1] == 0) & (np.abs(f[1:] - f[:-1]) <= 1e-9 * f[1:]))
        return f[single], np.where(w[single] == 0, 1, w[single])
    order = np.argsort(f[keep])
    return f[keep][order], w[keep][order]


#: speeds sampled by :func:`cross_coupled_critical_speeds` before refining each crossing
CROSSING_SAMPLES = 121


def cross_coupled_critical_speeds(ops: RotorOperators, turn: sp.spmatrix, max_hz: float | None = None,
                                  forward_only: bool = False, count: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """:func:`critical_speeds` of a rotor whose bearings are cross-coupled: the speeds Omega where a whirl
    frequency of the undamped rotor (M, Omega Gp1, K0 + Kbc; no bearing damping) equals Omega (ROSS's ``wd``
    crossing), the crossings of its Campbell
    curves with the 1x line (an unbalance then drives that mode at its frequency), and their whirl.

    The circulatory Kbc makes the roots grow or decay, so no real Omega solves the synchronous pencil; the
    j-th lowest whirl frequency f_j(Omega) is still a continuous function of the speed (an order statistic),
    so each sign change of f_j(Omega) - Omega (j over all count + 2 roots computed) on
    :data:`CROSSING_SAMPLES` speeds up to 1.3 times the ``count``-th critical speed without the cross coupling
    (at most ``max_hz``) is refined by Brent's method to 1e-10 of the speed."""
    from scipy.optimize import brentq

    # undamped: the bearings' damping leaves (linear_system adds C_b whenever it has entries), as in
    # _hermitian_critical_speeds, so that a vanishing cross coupling gives the same speeds; speed-dependent
    # bearings keep the coefficients ops was assembled with (the scene's speed, as the Hermitian pencil's: the
    # undamped critical speeds are solved for, not followed in speed), so no speed outside their table is read
    ops = replace(ops, Cb=sp.csr_matrix(ops.Cb.shape), bearing_change=None)
    base, _ = _hermitian_critical_speeds(replace(ops, Kbc=ops.Kbc * 0.0), turn, max_hz, False)
    top = 1.3 * float(base[min(count, base.size) - 1]) if base.size else 1.0
    top = top if max_hz is None else min(top, max_hz)
    m = count + 2

    def roots(speed):
        return state_eigenvalues(linear_system(ops, speed, frame="inertial"), m, vectors=True)

    def excess(speed, j):
        lam, _ = roots(speed)
        return frequencies_of(lam, m)[j] - speed

    grid = np.linspace(0.0, top, CROSSING_SAMPLES)
    table = np.array([frequencies_of(roots(s)[0], m) for s in grid]) - grid[:, None]
    found = []
    # every computed root, not the first count: an axial root (a thrust bearing's) takes a place among them
    for j in range(m):
        g = table[:, j]
        for i in np.flatnonzero(np.isfinite(g[:-1]) & np.isfinite(g[1:]) & (np.sign(g[:-1]) != np.sign(g[1:]))):
            speed = grid[i] if g[i] == 0.0 else brentq(excess, grid[i], grid[i + 1], args=(j,), xtol=1e-12 * top,
                                                       rtol=1e-10)
            lam, X = roots(speed)
            # the crossing root: the j-th by frequency (two roots of one frequency, a forward and a backward
            # one growing and decaying, are two crossings, each its own root)
            k = int(_oscillating(lam, m)[j])
            found.append((speed, int(whirl_sense(X[:, [k]], ops.basis, turn)[0])))
    f = np.array([s for s, _ in found])
    w = np.array([v for _, v in found], dtype=int)
    keep = (w != AXIAL) & ((w != -1) if forward_only else True)
    order = np.argsort(f[keep])
    return f[keep][order], np.where(w[keep][order] == 0, 1, w[keep][order]) if forward_only else w[keep][order]


def instability_onsets(ops: RotorOperators, speeds_hz: np.ndarray, growth: np.ndarray, count: int,
                       rayleigh=(0.0, 0.0), external: float = 0.0, frame: str = "inertial",
                       lowest_hz: float = 0.0) -> np.ndarray:
    """Speeds [Hz] where the growth rate turns positive between grid points (internal damping, cross-
    coupled bearings), each refined by bisection to 1e-6 of the speed.

    The grid's growth rates are clipped at their round-off resolution (:func:`growth_rate`); the
    bisection instead follows the root that grows at the bracket's unstable end, a simple root whose
    real part is accurate to round-off, and finds where that real part changes sign. ``lowest_hz``: the lowest
    speed the model is defined at (speed-dependent bearings: their tables' start); a rotor unstable there is
    reported unstable from there on."""
    def roots(speed):
        return state_eigenvalues(linear_system(ops, speed, 0.0, 0.0, rayleigh, external, frame), count)

    def grows(speed):
        system = linear_system(ops, speed, 0.0, 0.0, rayleigh, external, frame)
        return growth_rate(state_eigenvalues(system, count), count, _omega_max(system.M, system.Q)) > 0.0

    speeds_hz, growth = np.asarray(speeds_hz, dtype=float), np.asarray(growth, dtype=float)
    brackets = [(float(speeds_hz[i]), float(speeds_hz[i + 1]))
                for i in np.flatnonzero((growth[:-1] <= 0.0) & (growth[1:] > 0.0))]
    out = []
    if growth.size and growth[0] > 0.0:
        # unstable from the grid's first speed on: from rest (a bearing's cross coupling), or from
        # some speed below the grid
        first = float(speeds_hz[0])
        if first <= lowest_hz or grows(lowest_hz):
            out.append(max(lowest_hz, 0.0) if first > lowest_hz else first)
        else:
            brackets.insert(0, (lowest_hz, first))
    for a, b in brackets:
        lam = roots(b)
        track = lam[np.argmax(lam.real)]
        while b - a > 1e-6 * b:
            mid = 0.5 * (a + b)
            lam = roots(mid)
            track = lam[np.argmin(np.abs(lam - track))]
            if track.real > 0.0:
                b = mid
            else:
                a = mid
        out.append(0.5 * (a + b))
    return np.array(out)


WHIRL_NAMES = {1: "forward", -1: "backward", 0: "planar", AXIAL: "axial"}


def inertial_report(model, ops: dict, rot: Rotation, damp: Damping, speeds_hz, count: int, reduction) -> dict:
    """``campbell_report`` in the inertial frame: whirl frequencies marked forward or backward,
    critical speeds (synchronous whirl, what an unbalance drives), the speeds where the rotor turns
    unstable. Gravity is a constant load here: no gravity resonance."""
    from ..fem.components import lateral_turn

    top = None if reduction is None else reduction.info.get("max_frequency_hz")
    valid = VALID_FRACTION * top if top else math.inf
    turn = lateral_turn(model.spaces, model.n_full)
    isotropic = all(b.isotropic for b in model.stack.bearings)
    crit = {}
    for c, o in ops.items():
        # a rotor without contacts has one set of operators for both: its speeds once (a cross-coupled
        # rotor's crossing search costs a few hundred eigen solves)
        same = [d for d in crit if ops[d] is o]
        crit[c] = crit[same[0]] if same else critical_speeds(o, turn, None if math.isinf(valid) else valid, isotropic,
                                                             count + 2)
    if speeds_hz is None:
        # past the second forward critical speed (the first of the second mode pair)
        c = crit["open"][0][crit["open"][1] == 1]
        top = getattr(rot, "max_speed_hz", rot.speed_hz)   # a run-up: over its ramp too
        stop = max(1.23 * (c[min(1, len(c) - 1)] if len(c) else 0.0), 2.0 * top, 1.0)
        speeds = np.linspace(0.0, stop, 61)
    else:
        speeds = np.asarray(speeds_hz, dtype=float)
    rd = (damp.rayleigh, damp.external)
    res, onsets, damped = {}, {}, {}
    for c, o in ops.items():
        same = [d for d in res if ops[d] is o]  # no contacts: one set of operators, computed once
        if same:
            res[c], onsets[c], damped[c] = res[same[0]], onsets[same[0]], damped[same[0]]
            continue
        res[c] = campbell(o, speeds, count, *rd, frame="inertial", turn=turn)
        # (a bearing table starting above 0 Hz: nothing is known below its first row)
        lowest = max((b.table[0][0] for b in model.stack.bearings if b.table), default=0.0)
        onsets[c] = instability_onsets(o, speeds, res[c].growth_per_s, count, *rd, lowest_hz=lowest)
        damped[c] = damped_critical_speeds(o, res[c], count, *rd, turn=turn)

    warnings = reduction_warnings(model, damped["open"], count, rd, reduction)

    def clean(a):
        return [None if not np.isfinite(x) else float(x) for x in np.ravel(a)]

    def bands(c):
        g, out = res[c].growth_per_s, []
        for a in onsets[c]:
            back = np.flatnonzero((speeds > a) & (g <= 0.0))
            out.append([float(a), float(speeds[back[0]]) if len(back) else None])
        return out

    whirl = [[WHIRL_NAMES[int(w)] if np.isfinite(f) else None for w, f in zip(wr, fr)]
             for wr, fr in zip(res["open"].whirl, res["open"].frequencies_hz)]
    return {
        "frame": "inertial",
        "speeds_hz": clean(speeds),
        "frequencies_hz": [clean(row) for row in res["open"].frequencies_hz],
        "whirl": whirl,
        "frequencies_closed_hz": [clean(row) for row in res["closed"].frequencies_hz],
        "growth_rate_per_s": {c: clean(r.growth_per_s) for c, r in res.items()},
        "branches": {c: branches_json(r, WHIRL_NAMES) for c, r in res.items()},
        "critical_speeds_hz": {c: [x.speed_hz for x in v] for c, v in damped.items()},
        "critical_whirl": {c: [WHIRL_NAMES[x.whirl] for x in v] for c, v in damped.items()},
        "critical_speeds": {c: [{"speed_hz": x.speed_hz, "branch": x.branch, "whirl": WHIRL_NAMES[x.whirl],
                                 "whirl_at_speed": WHIRL_NAMES[x.whirl_at_speed], "damping_ratio": x.damping_ratio}
                                for x in v] for c, v in damped.items()},
        "undamped_critical_speeds_hz": {c: clean(v[0][:count]) for c, v in crit.items()},
        "undamped_critical_whirl": {c: [WHIRL_NAMES[int(w)] for w in v[1][:count]] for c, v in crit.items()},
        "gravity_resonances_hz": {"open": [], "closed": []},
        "gravity_excitation": {"open": [], "closed": []},
        "instability_hz": {c: clean(v) for c, v in onsets.items()},
        "instability_bands_hz": {c: bands(c) for c in res},
        "ndof_full": model.n, "ndof": model.n if reduction is None else reduction.ndof,
        "valid_up_to_hz": None if math.isinf(valid) else valid,
        "_results": res, "_bands": [(a, math.inf if b is None else b) for a, b in bands("open")],
        "warnings": warnings,
        "_critical": damped,
    }


def damped_critical_speeds(ops: RotorOperators, res, count: int, rayleigh=(0.0, 0.0), external: float = 0.0,
                           turn: sp.spmatrix | None = None):
    """Inertial frame: the speeds where the 1x line crosses a damped branch of the diagram ``res``
    (:func:`.campbell.campbell`), forward, backward and planar alike (axial modes left out: an unbalance
    does not drive them), each found by Brent's method on its tracked branch (:func:`.branches.crossings`);
    ``Crossing.branch`` indexes :func:`.campbell.shown_branches`."""
    from .branches import crossings
    from .campbell import root_function, shown_branches

    shown = shown_branches(res)
    B = res.branches
    sub = replace(B, eigenvalues=B.eigenvalues[shown], vectors=B.vectors[shown], whirl=B.whirl[shown],
                  label=B.label[shown])
    return crossings(sub, root_function(ops, count, rayleigh, external, "inertial", turn), ops.M, skip=(AXIAL,))


#: a reduced model's damped critical speed is reported as off when the full model's nearest root at that speed
#: whirls more than this fraction of the speed away
REDUCED_CRITICAL_TOLERANCE = 1e-3
#: full models up to this many dofs are checked (one eigen solve per critical speed)
REDUCED_CHECK_MAX_DOF = 2000


def reduction_warnings(model, crossings, count: int, rd, reduction) -> list[str]:
    """Warnings for the damped critical speeds (contacts open) of a reduced model that the full model does not
    confirm: at each speed s its roots (:func:`.campbell.state_eigenvalues`, the lowest 2 x ``count``) must hold
    one whirling within :data:`REDUCED_CRITICAL_TOLERANCE` s. Heavy bearing damping couples the kept modes to
    truncated ones, which a truncation judged by frequency alone misses (critical_speed, 12 modes: 88.00 and
    209.59 Hz against 85.74 and 221.09 Hz in full)."""
    from ..fem.rotating import rotor_operators
    from .campbell import TRACKED
    from .modes import contact_basis

    if reduction is None or not crossings or model.n > REDUCED_CHECK_MAX_DOF:
        return []
    ops = rotor_operators(model, contact_basis(model, "open"))
    off = []
    for c in crossings:
        lam = state_eigenvalues(linear_system(ops, c.speed_hz, 0.0, 0.0, *rd, "inertial"), TRACKED * count)
        f = lam.imag[lam.imag > 0] / (2 * math.pi)
        nearest = float(f[np.argmin(np.abs(f - c.speed_hz))]) if f.size else math.nan
        if not abs(nearest - c.speed_hz) <= REDUCED_CRITICAL_TOLERANCE * c.speed_hz:
            off.append(f"{c.speed_hz:.2f} Hz (full model's nearest root there: {nearest:.2f} Hz)")
    if not off:
        return []
    return [f"the reduced model's damped critical speeds {', '.join(off)} are off by more than "
            f"{100 * REDUCED_CRITICAL_TOLERANCE:g} %: the bearings' damping couples the kept modes to truncated "
            "ones; keep more modes (reduction.modes) or none (reduction.method = \"none\")"]


def unstable_warning(speed_hz: float, onsets_hz, bands) -> str | None:
    """Inertial frame: a warning when ``speed_hz`` lies where the rotor's motion grows (past an onset
    of instability: internal damping beyond its threshold, cross-coupled bearings), else None."""
    for a, b in bands:
        if a <= speed_hz and (b is None or speed_hz < b):   # onset 0: unstable at rest
            return (f"rotation.speed_hz = {speed_hz:g} Hz lies beyond the onset of instability at {a:.4g} Hz "
                    "(internal damping or cross-coupled bearings): free motion grows")
    return None


