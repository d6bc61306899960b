"""Point components on the rotor axis: rigid disks, bearings, unbalances (design section 8).

Each acts at one node of the segment that carries it (:meth:`~nsfem.stack.BeamStack.carrier`), on the
lateral values V, W and the slopes V', W' there (docs/theory.md, "Disks, bearings, unbalance"):

- disk: mass m on U, V and W, diametral inertia I_d on V' and W'. Its polar inertia I_p enters only
  with rotation: in the inertial frame as the gyroscopic couple Omega I_p (V' row, W' column +, W'
  row, V' column -); in the rotating frame as the Coriolis coupling (2 I_d - I_p) Omega and the
  centrifugal term (I_p - I_d) Omega^2 of the slopes, next to the translational 2 m Omega and
  -m Omega^2 (:func:`disk_rotating`).
- bearing: K = [[kyy, kyz], [kzy, kzz]] on (V, W) and C likewise; an axial spring kxx on U. K's
  symmetric part joins the structure's stiffness, its skew part (cross coupling) is circulatory.
- crack (an open crack's hinge, :class:`~nsfem.stack.Crack`): a rotational spring diag(1 / c_V', 1 / c_W')
  between the slopes of its two sides (:func:`crack_stiffness`); the hinge's shared U, V, W are
  constraints (:func:`nsfem.fem.assemble.support_and_junction_rows`).
- unbalance: magnitude m e at angle phi in the rotating frame: the load m e Omega^2 (cos phi, sin phi)
  on (V, W) there, and its quarter-turn (-sin phi, cos phi) for the harmonic load of the inertial
  frame (:func:`unbalance_loads`).

All functions take the stack and a ``dof(segment, name, x)`` numbering and return full-coordinate
operators (n_full x n_full sparse, or vectors), as :mod:`nsfem.fem.rotating` does.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from ..stack import BeamStack

Dof = Callable[[str, str, float], int]


def _node(stack: BeamStack, dof: Dof, x: float, names=("V", "W", "V'", "W'")) -> list[int]:
    seg = stack.carrier(x)
    return [dof(seg, name, x) for name in names]


def _sparse(entries: list[tuple[int, int, float]], n: int) -> sp.csr_matrix:
    if not entries:
        return sp.csr_matrix((n, n))
    r, c, v = zip(*entries)
    return sp.csr_matrix((v, (r, c)), shape=(n, n))


def disk_mass(stack: BeamStack, dof: Dof, n: int) -> sp.csr_matrix:
    """The disks' mass: m on U, V and W, I_d on V' and W' at each disk's node."""
    out = []
    for d in stack.disks:
        u, v, w, vs, ws = _node(stack, dof, d.x, ("U", "V", "W", "V'", "W'"))
        out += [(u, u, d.mass), (v, v, d.mass), (w, w, d.mass), (vs, vs, d.diametral), (ws, ws, d.diametral)]
    return _sparse(out, n)


def disk_gyroscopic(stack: BeamStack, dof: Dof, n: int) -> sp.csr_matrix:
    """Inertial frame, per unit speed: the disks' gyroscopic matrix, I_p at (V', W') and -I_p at (W', V')
    (skew). With H = I_p Omega (1, V', W') the spin's angular momentum, its rate I_p Omega (V'', W'')
    ... is the couple; the free disk then nutates forward at I_p Omega / I_d."""
    out = []
    for d in stack.disks:
        _, _, vs, ws = _node(stack, dof, d.x)
        out += [(vs, ws, d.polar), (ws, vs, -d.polar)]
    return _sparse(out, n)


def disk_rotating(stack: BeamStack, dof: Dof, n: int) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray,
                                                                  np.ndarray, np.ndarray]:
    """Rotating frame, per unit speed: the disks' (G1, Kc1, Fy, Fz, fc1) parts, as for the shaft in
    :mod:`nsfem.fem.rotating`: Coriolis 2 m on (W, V) and (2 I_d - I_p) on (W', V') (skew), centrifugal
    -m on V, W and (I_p - I_d) on V', W', the gravity loads m on V and W, and the centrifugal load
    m (y_c, z_c) of a disk on an offset segment."""
    G, K = [], []
    Fy, Fz, fc = np.zeros(n), np.zeros(n), np.zeros(n)
    for d in stack.disks:
        v, w, vs, ws = _node(stack, dof, d.x)
        m, c = d.mass, 2.0 * d.diametral - d.polar
        G += [(w, v, 2.0 * m), (v, w, -2.0 * m), (ws, vs, c), (vs, ws, -c)]
        K += [(v, v, -m), (w, w, -m), (vs, vs, d.polar - d.diametral), (ws, ws, d.polar - d.diametral)]
        Fy[v] += m
        Fz[w] += m
        yc, zc = stack.segment(stack.carrier(d.x)).offset
        fc[v] += m * yc
        fc[w] += m * zc
    return _sparse(G, n), _sparse(K, n), Fy, Fz, fc


def bearing_matrices(stack: BeamStack, dof: Dof, n: int) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """(K_b, K_c, C_b): the bearings' stiffness split into its symmetric part K_b (lateral, with the
    axial kxx on U: potential energy, part of the structure's K) and its skew part K_c (the cross
    coupling kyz - kzy of a fluid film: circulatory, a force no potential gives), and their damping."""
    K, Kc, C = [], [], []
    for b in stack.bearings:
        v, w = _node(stack, dof, b.x, ("V", "W"))
        for i, r in enumerate((v, w)):
            for j, c in enumerate((v, w)):
                sym, skew = (b.K[i][j] + b.K[j][i]) / 2, (b.K[i][j] - b.K[j][i]) / 2
                if sym:
                    K.append((r, c, sym))
                if skew:
                    Kc.append((r, c, skew))
                if b.C[i][j]:
                    C.append((r, c, b.C[i][j]))
        if b.kxx:
            (u,) = _node(stack, dof, b.x, ("U",))
            K.append((u, u, b.kxx))
    return _sparse(K, n), _sparse(Kc, n), _sparse(C, n)


def unbalance_loads(stack: BeamStack, dof: Dof, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per unit Omega^2: (fu, fu_quarter), the unbalances' load m e (cos phi, sin phi) on (V, W) and the
    same turned a quarter forwards, m e (-sin phi, cos phi)."""
    fu, fq = np.zeros(n), np.zeros(n)
    for u in stack.unbalances:
        v, w = _node(stack, dof, u.x, ("V", "W"))
        c, s = np.cos(u.phase), np.sin(u.phase)
        fu[v] += u.magnitude * c
        fu[w] += u.magnitude * s
        fq[v] -= u.magnitude * s
        fq[w] += u.magnitude * c
    return fu, fq


def lateral_turn(spaces: dict, n: int) -> sp.csr_matrix:
    """J: a quarter turn about x of every lateral pair, (J q)_V = -q_W and (J q)_W = q_V (values and
    slopes alike; V and W share one Hermite numbering per segment). The velocity of a frame turning at
    Omega adds Omega J q to the rates a frame turning with it sees."""
    rows, cols, vals = [], [], []
    for space in spaces.values():
        V, W = space.dofs["V"], space.dofs["W"]
        rows += [V, W]
        cols += [W, V]
        vals += [-np.ones(V.size), np.ones(V.size)]
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


def crack_stiffness(stack: BeamStack, dof: Dof, n: int) -> sp.csr_matrix:
    """The open cracks' rotational springs: energy (1/2) sum_s (s'_right - s'_left)^2 / c_s' over the slopes
    s' = V', W' at each crack (stiffness [[k, -k], [-k, k]] on the two sides' slope dofs)."""
    out = []
    for k in stack.cracks:
        left, right = k.segments
        for name, c in zip(("V'", "W'"), k.compliance):
            a, b = dof(left, name, k.x), dof(right, name, k.x)
            out += [(a, a, 1.0 / c), (b, b, 1.0 / c), (a, b, -1.0 / c), (b, a, -1.0 / c)]
    return _sparse(out, n)
