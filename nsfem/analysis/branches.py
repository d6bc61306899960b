"""Campbell branches: each damped mode followed in speed by the continuity of its shape, and the speeds
where a branch crosses the 1x line (the damped critical speeds).

Sorting the roots by frequency at each speed joins different modes wherever two branches cross. A
branch here is one mode: the roots at neighbouring speeds are paired by the largest mass-weighted
modal assurance criterion of their eigenvectors,

    MAC(a, b) = |a^H M b|^2 / ((a^H M a) (b^H M b)),

which is insensitive to the complex scale of an eigenvector, 1 for one shape, 0 for M-orthogonal ones
(forward and backward whirl of one shape, the two bending planes). A degenerate group at one speed
(a round rotor's pair at rest) is matched by its span. A step where a root finds no partner or a
pair matches poorly is halved (:func:`refine`). A root left unpaired (a complex pair born from two
real, overdamped roots, or entering the computed window) starts a new branch.

A branch crosses 1x where g(Omega) = f(Omega) - Omega changes sign between two speeds of the grid;
the crossing is refined by Brent's method on g, with f(Omega) the frequency of the root that best
matches the branch's eigenvectors at the bracket's ends (only at ends with Omega > 0: at rest an
isotropic pair's eigenvectors are any combination of its forward and backward whirl).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

#: Roots at neighbouring speeds are one mode only if their MAC is at least this (a mode's shape
#: changes little between neighbouring speeds, MAC near 1; an unrelated shape, MAC near 0)
MAC_MIN = 0.5
#: weight of the relative eigenvalue distance against the MAC in the pairing: it only breaks ties (one
#: shape at two frequencies, as an isotropic rotor's rotating-frame branches omega +- Omega)
EIG_WEIGHT = 0.1
#: roots closer than this relative distance are one degenerate group (:func:`_subspace_mac`)
DEGENERATE = 1e-7
#: a step is halved (:func:`refine`) when a pair's MAC is below this (a shape changing fast)
MAC_GOOD = 0.9
#: at most this many halvings of a speed step
REFINE_DEPTH = 5
#: Brent's method stops within this fraction of the speed range (the marker's speed is exact to it)
XTOL = 1e-11

#: ``roots(speed)`` -> (eigenvalues with Im > 0 [rad/s], displacement eigenvectors n x k, whirl codes (k,))
RootFunction = Callable[[float], "tuple[np.ndarray, np.ndarray, np.ndarray]"]


@dataclass(frozen=True)
class Branches:
    """Tracked branches: row b of each array is one mode over the speeds (nan / 0 where it does not exist)."""

    speeds_hz: np.ndarray     # (S,)
    eigenvalues: np.ndarray   # (B, S) complex [rad/s], nan where the branch does not exist
    vectors: np.ndarray       # (B, S, n) complex displacement eigenvectors
    whirl: np.ndarray         # (B, S) whirl code per point (nsfem.analysis.whirl; 0 without a turn)
    label: np.ndarray         # (B,) the branch's whirl code: its whirl at its highest speed
    reported: np.ndarray      # (S,) True at the speeds asked for (False: inserted by refine)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """(B, S) damped natural frequencies [Hz], nan where a branch does not exist."""
        return self.eigenvalues.imag / (2 * math.pi)

    @property
    def damping_ratios(self) -> np.ndarray:
        """(B, S) -Re(lambda) / |lambda| (negative: the mode grows)."""
        return -self.eigenvalues.real / np.abs(self.eigenvalues)


@dataclass(frozen=True)
class Crossing:
    """A damped critical speed: branch ``branch`` whirls at the rotor speed ``speed_hz``."""

    speed_hz: float
    branch: int
    whirl: int                # the branch's label
    damping_ratio: float
    eigenvalue: complex
    whirl_at_speed: int = 0   # the crossing root's own whirl (the label is the branch's at its highest speed)


def mac(M: sp.spmatrix | np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(i, j) -> mass-weighted modal assurance criterion of columns A[:, i] and B[:, j]."""
    MB = M @ B
    cross = np.abs(A.conj().T @ MB) ** 2
    na = np.einsum("ij,ij->j", A.conj(), M @ A).real
    nb = np.einsum("ij,ij->j", B.conj(), MB).real
    return cross / np.maximum(np.outer(na, nb), 1e-300)


def _subspace_mac(M, A: np.ndarray, lam: np.ndarray, B: np.ndarray) -> np.ndarray:
    """:func:`mac` of columns A and B, but for a column of A in a group of equal eigenvalues (relative
    :data:`DEGENERATE`: a round rotor's pair at rest, whose eigenvectors are any basis of its plane) the
    share of B's column in the group's span, x^H M P x / x^H M x with P the M-orthogonal projector."""
    C = mac(M, A, B)
    done = np.zeros(lam.size, dtype=bool)
    for i in range(lam.size):
        if done[i]:
            continue
        group = np.flatnonzero(np.abs(lam - lam[i]) <= DEGENERATE * np.abs(lam[i]))
        done[group] = True
        if group.size < 2:
            continue
        V = A[:, group]
        G = V.conj().T @ (M @ V)                       # Gram matrix of the span
        W = V.conj().T @ (M @ B)
        proj = np.einsum("ij,ij->j", W.conj(), np.linalg.lstsq(G, W, rcond=None)[0]).real
        nb = np.einsum("ij,ij->j", B.conj(), M @ B).real
        C[group] = np.clip(proj / np.maximum(nb, 1e-300), 0.0, 1.0)[None, :]
    return C


def pair(M, a: tuple, b: tuple, step_hz: float) -> dict[int, tuple[int, float]]:
    """Roots of ``a`` paired with roots of ``b`` (each (eigenvalues, vectors, ...), ``step_hz`` apart):
    {index in a: (index in b, MAC)}, by the largest total MAC (an assignment problem) among pairs with
    MAC >= :data:`MAC_MIN`; then the roots left over through zero frequency (the rotating frame's
    f0 - Omega past Omega = f0 goes on as the conjugate root, whose vector is the conjugate)."""
    from scipy.optimize import linear_sum_assignment

    lam0, X0 = a[0], a[1]
    lam, X = b[0], b[1]
    out: dict[int, tuple[int, float]] = {}
    taken: set[int] = set()
    for conjugate in (False, True):
        free = [i for i in range(lam0.size) if i not in out]
        new = [k for k in range(lam.size) if k not in taken]
        if not free or not new:
            break
        A = X0[:, free].conj() if conjugate else X0[:, free]
        a0 = lam0[free].conj() if conjugate else lam0[free]
        C = _subspace_mac(M, A, a0, X[:, new])
        # ties (one shape at two frequencies) go to the nearer root
        D = np.abs(a0[:, None] - lam[new][None, :]) / (np.abs(a0)[:, None] + np.abs(lam[new])[None, :])
        r, c = linear_sum_assignment(-(C - EIG_WEIGHT * D))
        # through zero only: both frequencies within the speed step (f0 - Omega moves by it)
        near = (np.abs(a0.imag)[:, None] + np.abs(lam[new].imag)[None, :] <= 2 * 2 * math.pi * abs(step_hz)
                if conjugate else np.ones_like(C, dtype=bool))
        for i, k in zip(r, c):
            if C[i, k] >= MAC_MIN and near[i, k]:
                out[free[i]] = (new[k], float(C[i, k]))
                taken.add(new[k])
    return out


def refine(speeds_hz: np.ndarray, roots: list, root_function: RootFunction | None, M,
           depth: int = REFINE_DEPTH) -> tuple[np.ndarray, list, np.ndarray]:
    """The grid with midpoints inserted (at most ``depth`` halvings of a step) wherever a root of one speed
    finds no partner at the next (:func:`pair`) or a pair's MAC is below :data:`MAC_GOOD`: a step too
    coarse for the shapes' change (or a root dying there: a pair turning real, leaving the window).
    Returns (speeds, roots, mask of the given speeds)."""
    grid = [(float(s), r, True, 0) for s, r in zip(np.asarray(speeds_hz, dtype=float), roots)]
    if root_function is None:
        return np.array([g[0] for g in grid]), [g[1] for g in grid], np.ones(len(grid), dtype=bool)
    i = 0
    while i < len(grid) - 1:
        (sa, a, _, da), (sb, b, _, db) = grid[i], grid[i + 1]
        level = max(da, db)
        if level < depth and sb > sa:
            p = pair(M, a, b, sb - sa)
            if len(p) < a[0].size or min((m for _, m in p.values()), default=1.0) < MAC_GOOD:
                sm = 0.5 * (sa + sb)
                grid.insert(i + 1, (sm, root_function(sm), False, level + 1))
                continue
        i += 1
    return np.array([g[0] for g in grid]), [g[1] for g in grid], np.array([g[2] for g in grid])


def track(speeds_hz: np.ndarray, roots: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
          M: sp.spmatrix | np.ndarray, root_function: RootFunction | None = None) -> Branches:
    """Branches through the roots at each speed (``roots[i]``: eigenvalues with Im > 0, their displacement
    eigenvectors as columns, their whirl codes), paired between neighbouring speeds by :func:`pair`; with
    ``root_function``, on the grid :func:`refine` makes of the speeds (``Branches.reported`` marks the
    given ones)."""
    speeds, roots, reported = refine(speeds_hz, roots, root_function, M)
    S = speeds.size
    n = M.shape[0]
    rows: list[dict[int, int]] = []  # branch -> {speed index: root index}
    owner: dict[int, int] = {}       # root index at the previous speed -> its branch
    for i, r in enumerate(roots):
        links = pair(M, roots[i - 1], r, speeds[i] - speeds[i - 1]) if i else {}
        now: dict[int, int] = {}
        for j, (k, _) in links.items():
            rows[owner[j]][i] = k
            now[k] = owner[j]
        for k in range(r[0].size):
            if k not in now:
                rows.append({i: k})
                now[k] = len(rows) - 1
        owner = now
    B = len(rows)
    lam_b = np.full((B, S), complex(np.nan, np.nan))
    vec_b = np.zeros((B, S, n), dtype=complex)
    whirl_b = np.zeros((B, S), dtype=int)
    for b, row in enumerate(rows):
        for i, k in row.items():
            lam, X, W = roots[i]
            lam_b[b, i], vec_b[b, i], whirl_b[b, i] = lam[k], X[:, k], W[k]
    label = np.array([whirl_b[b, max(row)] for b, row in enumerate(rows)], dtype=int)
    # ascending by the frequency where each branch starts
    first = np.array([lam_b[b, min(row)].imag for b, row in enumerate(rows)]) if B else np.zeros(0)
    start = np.array([min(row) for row in rows]) if B else np.zeros(0, dtype=int)
    order = np.lexsort((first, start)) if B else np.zeros(0, dtype=int)
    return Branches(speeds, lam_b[order], vec_b[order], whirl_b[order], label[order], reported)


def crossings(branches: Branches, roots: RootFunction, M, skip=()) -> list[Crossing]:
    """Damped critical speeds: every sign change of f_b(Omega) - Omega on the grid (branches whose label
    is in ``skip`` left out, e.g. axial modes), refined by Brent's method on the tracked branch to
    :data:`XTOL` of the speed range. ``roots`` computes (eigenvalues, vectors, whirl) at one speed."""
    from scipy.optimize import brentq

    s = branches.speeds_hz
    span = float(s.max() - s.min()) if s.size else 0.0
    F = branches.frequencies_hz
    out = []
    for b in range(F.shape[0]):
        if branches.label[b] in skip:
            continue
        g = F[b] - s
        for i in range(s.size):
            if g[i] == 0.0 and s[i] > 0:
                lam = branches.eigenvalues[b, i]
                out.append(Crossing(float(s[i]), b, int(branches.label[b]), float(-lam.real / abs(lam)), complex(lam),
                                    int(branches.whirl[b, i])))
        for i in np.flatnonzero(np.isfinite(g[:-1]) & np.isfinite(g[1:]) & (g[:-1] * g[1:] < 0.0)):
            refs = [branches.vectors[b, j] for j in (i, i + 1) if s[j] > 0.0]
            R = np.column_stack(refs)

            def follow(speed, R=R):
                lam, X, W = roots(speed)
                k = int(np.argmax(mac(M, R, X).sum(axis=0)))
                return lam[k], int(W[k])

            speed = brentq(lambda x: follow(x)[0].imag / (2 * math.pi) - x, s[i], s[i + 1],
                           xtol=XTOL * max(span, 1.0), rtol=4 * np.finfo(float).eps)
            lam, here = follow(speed)
            out.append(Crossing(float(speed), b, int(branches.label[b]), float(-lam.real / abs(lam)), complex(lam),
                                here))
    return sorted(out, key=lambda c: c.speed_hz)
