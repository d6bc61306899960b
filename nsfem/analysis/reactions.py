"""Static loads on a rotor's parts: bearing and support reactions, the shaft's deflection (sag).

All functions take the model and a displacement in full finite-element coordinates (q_full = T q for a
reduction's T) and return arrays; forces are in N, lateral components along y and z of the frame the
coordinates are in (the rotating frame's for a state stationary there).

A bearing pushes on the shaft with -K u - C u' (u = (V, W) at its node); a state stationary in the
rotating frame moves in space at Omega J u, so a bearing fixed in space adds the damping force
-Omega C J u there (:func:`bearing_reactions`). A support's reaction is the constraint force that holds
its dofs: the residual r = Q q - f of the unconstrained equations, carried by the constraint rows
(:func:`support_reactions`).

>>> from nsfem import build_model, load_scene
>>> model = build_model(load_scene("ross_example", ["reduction.method=none", "mesh.elements=6"]))
>>> bearing_reactions(model, np.zeros(model.n_full)).tolist()
[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

#: J of a lateral pair (V, W): a quarter turn about x, (J u)_V = -u_W, (J u)_W = u_V
QUARTER_TURN = np.array([[0.0, -1.0], [1.0, 0.0]])


def node_lateral(model, x: float, q_full: np.ndarray, segment: str | None = None) -> np.ndarray:
    """(V, W) of the shaft centre at ``x`` (on ``segment``, default the carrier of a point component)."""
    seg = segment or model.stack.carrier(x)
    return np.array([q_full[model.dof(seg, "V", x)], q_full[model.dof(seg, "W", x)]])


def bearing_reactions(model, q_full: np.ndarray, omega: float = 0.0, frame: str = "inertial") -> np.ndarray:
    """The force of each bearing on the shaft, (n_bearings, 2) [N] along (y, z): -K u, and in the rotating
    frame at ``omega`` [rad/s] also the damping of a bearing fixed in space, -omega C J u."""
    out = np.zeros((len(model.stack.bearings), 2))
    for i, b in enumerate(model.stack.bearings):
        u = node_lateral(model, b.x, q_full)
        A = np.asarray(b.K, dtype=float)
        if omega and frame == "rotating":
            A = A + omega * np.asarray(b.C, dtype=float) @ QUARTER_TURN
        out[i] = -A @ u
    return out


def bearing_force_histories(model, basis: np.ndarray, t: np.ndarray, q: np.ndarray, v: np.ndarray,
                            frame: str = "inertial", speed_hz: float = 0.0, phase_deg: float = 0.0) -> np.ndarray:
    """The force of each bearing on the shaft over time, (len(t), n_bearings, 3) [N] along (x, y, z) of the
    inertial frame (a bearing is fixed in space): -K u - C u' laterally, -kxx U axially, from reduced
    coordinates q, v (n, len(t)) with q_full = basis q. A run in the rotating frame is turned into the inertial
    one first: u = R(theta) u_r, u' = R(theta) (u_r' + Omega J u_r), theta = Omega t + phi."""
    t = np.asarray(t, dtype=float)
    out = np.zeros((t.size, len(model.stack.bearings), 3))
    omega = 2 * math.pi * speed_hz
    theta = omega * t + math.radians(phase_deg)
    for i, b in enumerate(model.stack.bearings):
        seg = model.stack.carrier(b.x)
        rows = basis[[model.dof(seg, "V", b.x), model.dof(seg, "W", b.x)]]
        u, du = rows @ q, rows @ v   # (2, times)
        if frame == "rotating" and omega:
            du = du + omega * (QUARTER_TURN @ u)
            c, s_ = np.cos(theta), np.sin(theta)
            u = np.array([c * u[0] - s_ * u[1], s_ * u[0] + c * u[1]])
            du = np.array([c * du[0] - s_ * du[1], s_ * du[0] + c * du[1]])
        out[:, i, 1:] = -(np.asarray(b.K, dtype=float) @ u + np.asarray(b.C, dtype=float) @ du).T
        if b.kxx:
            out[:, i, 0] = -b.kxx * (basis[model.dof(seg, "U", b.x)] @ q)
    return out


def bearing_names(model) -> list[str]:
    """Each bearing's name: its label, else ``bearing.<index>``."""
    return [b.label or f"bearing.{i}" for i, b in enumerate(model.stack.bearings)]


def bearing_columns(model) -> tuple[list[str], np.ndarray]:
    """(column names, (bearing, axis) index pairs) of bearings.csv: per bearing with lateral stiffness or
    damping ``<name>.Fy``, ``<name>.Fz``, and with an axial spring (kxx) ``<name>.Fx`` [N]."""
    names, index = [], []
    for i, (b, name) in enumerate(zip(model.stack.bearings, bearing_names(model))):
        lateral = bool(np.any(np.asarray(b.K)) or np.any(np.asarray(b.C)))
        for k, axis in ((1, "y"), (2, "z")) * lateral + ((0, "x"),) * bool(b.kxx):
            names.append(f"{name}.F{axis}")
            index.append((i, k))
    return names, np.array(index, dtype=int).reshape(-1, 2)


def write_bearings_csv(path, t: np.ndarray, columns: list[str], index: np.ndarray, forces: np.ndarray):
    """bearings.csv: a column ``t`` [s], then one per bearing force component [N] (written atomically)."""
    from ..atomic import write_text_atomic

    values = forces[:, index[:, 0], index[:, 1]]
    rows = [",".join(repr(float(x)) for x in (ti, *vals)) for ti, vals in zip(t, values)]
    return write_text_atomic(path, "\n".join([",".join(["t", *columns]), *rows]) + "\n")


def constraint_rows(model):
    """(C, labels): the support and junction rows C q_full = 0 and per row the support index it belongs to
    (None for a junction's or a crack hinge's row), in the order of
    :func:`nsfem.fem.assemble.support_and_junction_rows`."""
    from ..fem.assemble import support_and_junction_rows

    C, _ = support_and_junction_rows(model, model.stack)
    owner = [i for i, s in enumerate(model.stack.supports) for _ in s.fix]
    return C, owner + [None] * (C.shape[0] - len(owner))


def support_reactions(model, residual: np.ndarray) -> np.ndarray:
    """The force of each support on the shaft, (n_supports, 2) [N] along (y, z), from the residual
    r = Q q_full - f - (contact forces) of the unconstrained equations: r = C^T lam, lam the constraint
    forces (least squares: with a reduction the residual also holds the reduction's error off the
    constrained dofs). A support that fixes neither V nor W gets 0."""
    C, owner = constraint_rows(model)
    out = np.zeros((len(model.stack.supports), 2))
    if C.shape[0] == 0:
        return out
    Ct = sp.csr_matrix(C.T)
    rows = np.unique(Ct.nonzero()[0])
    lam = np.linalg.lstsq(Ct[rows].toarray(), residual[rows], rcond=None)[0]
    k = 0
    for i, s in enumerate(model.stack.supports):
        for name in s.fix:
            if name in ("V", "W"):
                out[i, "VW".index(name)] = lam[k]
            k += 1
    return out


def lateral_total(model, f_full: np.ndarray) -> np.ndarray:
    """The resultant (y, z) [N] of a load in full coordinates: the sum of its entries on the nodal values of
    V and W (Hermite value shape functions sum to one; the slope entries are moments)."""
    out = np.zeros(2)
    for space in model.spaces.values():
        nod = space.bending.nodal_dofs[0]
        out += [f_full[space.dofs["V"][nod]].sum(), f_full[space.dofs["W"][nod]].sum()]
    return out


def shaft_deflection(model, q_full: np.ndarray) -> dict:
    """The largest lateral deflection |(V, W)| over every node of every segment: ``{"x_m", "segment",
    "deflection_m": [y, z], "magnitude_m"}``."""
    best = None
    for name, space in model.spaces.items():
        nod = space.bending.nodal_dofs[0]
        vw = np.column_stack([q_full[space.dofs["V"][nod]], q_full[space.dofs["W"][nod]]])
        mag = np.hypot(vw[:, 0], vw[:, 1])
        k = int(np.argmax(mag))
        if best is None or mag[k] > best["magnitude_m"]:
            best = {"x_m": float(space.x[k]), "segment": name, "deflection_m": vw[k].tolist(),
                    "magnitude_m": float(mag[k])}
    return best


def disk_deflections(model, q_full: np.ndarray) -> list[dict]:
    """Per disk ``{"label", "x_m", "deflection_m": [y, z], "magnitude_m"}``: the shaft centre's (V, W) there."""
    out = []
    for i, d in enumerate(model.stack.disks):
        u = node_lateral(model, d.x, q_full)
        out.append({"label": d.label or f"disk.{i}", "x_m": d.x, "deflection_m": u.tolist(),
                    "magnitude_m": float(math.hypot(*u))})
    return out


__all__ = ["bearing_columns", "bearing_force_histories", "bearing_names", "write_bearings_csv", "bearing_reactions", "constraint_rows", "disk_deflections", "lateral_total", "node_lateral",
           "shaft_deflection", "support_reactions"]
