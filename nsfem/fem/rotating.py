"""Speed-independent operators of the rotating frame (design section 3, paper eq. 22, 25).

Assembled once per model and scaled per speed Omega [rad/s]:

- Coriolis        G = Omega G1,   G1 = 2 int rhoA (N_W N_V^T - N_V N_W^T) dx   (skew)
- centrifugal     Kc = Omega^2 Kc1,  Kc1 = -int rhoA (N_V N_V^T + N_W N_W^T) dx   (nsd, eq. 25)
  [+ int rho (I_z N_V' N_V'^T + I_y N_W' N_W'^T) dx for Rayleigh beams; Timoshenko's use their rotation
  functions N_psi here and their displacement functions N_v for N (:mod:`nsfem.fem.timoshenko`)]
- external damping (c_e per unit length, on the inertial lateral velocity):
  D_e = c_e De1, De1 = int (N_V N_V^T + N_W N_W^T) dx;  circulatory P = Omega c_e P1,
  P1 = int (N_W N_V^T - N_V N_W^T) dx (skew);  drag load Omega c_e fd1, fd1 = int (z_c N_V - y_c N_W)
- centrifugal load f_c = Omega^2 fc1,  fc1 = int rhoA (y_c N_V + z_c N_W) dx
- gravity         f_g(t) = g_y(t) Fy + g_z(t) Fz,  Fy = int rhoA N_V, Fz = int rhoA N_W,
  g_y = -g sin(Omega t + phi), g_z = -g cos(Omega t + phi)

With u = (U - eta V' - zeta W', V, W) in the rotating frame, Omega x u_dot and
Omega x (Omega x r) have no axial component. A Rayleigh beam keeps the section's
rotation in its kinetic energy; to the same (second) order a rotated section's points
move towards the axis by zeta W'^2 / 2 (eta V'^2 / 2), which lowers the centrifugal
potential: the stiffening term in brackets, without which a tilted rigid Rayleigh shaft
would not whirl at exactly Omega. (The axial inertia of offset sub-beams carries the same
kind of term in a fully consistent second-order model; eq. 25 leaves it out, so a free
delaminated rotor's rigid tilt sits about 1e-4 off Omega.)

>>> import numpy as np
>>> from nsfem import build_model, load_scene
>>> ops = rotor_operators(build_model(load_scene(None, ["mesh.elements=20"])))
>>> bool(abs(ops.G1 + ops.G1.T).max() == 0), bool(abs(ops.P1 + ops.P1.T).max() == 0)
(True, True)
>>> bool(np.linalg.eigvalsh(ops.Kc1.toarray()).max() <= 1e-12 * abs(ops.Kc1).max())   # nsd (E-B)
True
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Callable

import numpy as np
import scipy.sparse as sp

from . import components, hermite, timoshenko
from .assemble import ROTARY_THEORIES, FEModel, SegmentSpace
from .constraints import project


@dataclass(frozen=True)
class RotorOperators:
    """Mass, elastic stiffness and the speed-independent rotating-frame operators.

    ``basis`` is the T with q_full = T q they are expressed in (``None``: full coordinates).
    """

    M: sp.csr_matrix
    K0: sp.csr_matrix
    G1: sp.csr_matrix
    Kc1: sp.csr_matrix
    De1: sp.csr_matrix
    P1: sp.csr_matrix
    fc1: np.ndarray
    fd1: np.ndarray
    Fy: np.ndarray
    Fz: np.ndarray
    # rotor components (design section 8; zero without them) and the inertial frame's operators
    Kb: sp.csr_matrix            # the bearings' part of K0 (Rayleigh's beta K damps the shaft only)
    Kbc: sp.csr_matrix           # the bearings' cross coupling: skew, circulatory, in Q but not in K0
    Cb: sp.csr_matrix            # bearing damping
    CbJ: sp.csr_matrix           # C_b J: a fixed bearing's damping seen from the rotating frame (x Omega)
    MJ: sp.csr_matrix            # M J and (K0 - Kb) J: rotating internal damping seen from the inertial
    KJ: sp.csr_matrix            # frame (x -Omega alpha, -Omega beta)
    Gp1: sp.csr_matrix           # inertial frame: gyroscopic couple of the spin (x Omega), skew
    fu1: np.ndarray              # unbalance load per Omega^2 along its rotating-frame direction
    fq1: np.ndarray              # ... and turned a quarter forwards (inertial frame's harmonic)
    basis: sp.csr_matrix | np.ndarray | None = None
    #: speed-dependent bearings: speed [Hz] -> the changes of (Kb, Kbc, Cb, Cb J) from the assembled ones, in full
    #: coordinates (:func:`bearing_change`); None: the bearings' coefficients are constant
    bearing_change: Callable[[float], tuple] | None = None

    @property
    def n(self) -> int:
        return self.M.shape[0]

    def at_speed(self, speed_hz: float) -> "RotorOperators":
        """The operators with the bearings' coefficients at ``speed_hz`` (themselves without a speed table)."""
        if self.bearing_change is None:
            return self
        dKb, dKbc, dCb, dCbJ = (d if self.basis is None else project(self.basis, d)
                                for d in self.bearing_change(speed_hz))
        return replace(self, K0=(self.K0 + dKb).tocsr(), Kb=(self.Kb + dKb).tocsr(), Kbc=(self.Kbc + dKbc).tocsr(),
                       Cb=(self.Cb + dCb).tocsr(), CbJ=(self.CbJ + dCbJ).tocsr(), bearing_change=None)

    def project(self, T: sp.spmatrix) -> "RotorOperators":
        """Every operator in the coordinates q of q_full = T q (symmetry and skewness kept)."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("basis", "bearing_change"):
                continue
            out[f.name] = project(T, v) if sp.issparse(v) else np.asarray(T.T @ v)
        base = T if self.basis is None else self.basis @ T
        return replace(self, **out, basis=base)


def rotor_operators(model: FEModel, basis: sp.spmatrix | None = None) -> RotorOperators:
    """Assemble the operators of ``model`` and express them in ``basis`` (default: model.T).

    To express one assembly in several bases, call :func:`full_operators` once and
    :meth:`RotorOperators.project` per basis.
    """
    return full_operators(model).project(model.T if basis is None else basis)


def full_operators(model: FEModel) -> RotorOperators:
    """The operators in full finite-element coordinates (before supports and junctions)."""
    n = model.n_full
    names = ("G1", "Kc1", "De1", "P1", "Gp1")
    rows, cols, vals = ({k: [] for k in names} for _ in range(3))
    vec = {k: np.zeros(n) for k in ("fc1", "fd1", "Fy", "Fz")}

    def put(name, r, c, A):
        A = sp.coo_matrix(A)
        rows[name].append(r[A.row])
        cols[name].append(c[A.col])
        vals[name].append(A.data)

    rotary = model.stack.theory in ROTARY_THEORIES
    for s in model.stack.segments:
        space = model.spaces[s.name]
        u = space.unit
        # int N_v N_v per plane (with shear the planes' Phi differ for a rectangle) and int N_v dx
        MV, MW = u["mass_V"], u["mass_W"]
        # a coupling of the planes (Coriolis, circulatory, the spin's couple) integrates V's functions against
        # W's: int N_v^V N_v^W, either plane's own when their Phi agree (circles, squares, no shear)
        Mx = mixed_mass(space) if space.phi else MV
        loadV, loadW = (hermite.assemble_weighted(space.x, np.ones_like, phi=space.shear(f)) for f in ("V", "W"))
        V, W = space.dofs["V"], space.dofs["W"]
        rA = s.rho * s.area
        yc, zc = s.offset
        put("G1", W, V, 2 * rA * Mx.T)
        put("G1", V, W, -2 * rA * Mx)
        put("Kc1", V, V, -rA * MV)
        put("Kc1", W, W, -rA * MW)
        if rotary:
            put("Kc1", V, V, s.rho * s.I_z * u["rotary_V"])
            put("Kc1", W, W, s.rho * s.I_y * u["rotary_W"])
        put("De1", V, V, MV)
        put("De1", W, W, MW)
        put("P1", W, V, Mx.T)
        put("P1", V, W, -Mx)
        vec["fc1"][V] += rA * yc * loadV
        vec["fc1"][W] += rA * zc * loadW
        vec["fd1"][V] += zc * loadV
        vec["fd1"][W] += -yc * loadW
        vec["Fy"][V] += rA * loadV
        vec["Fz"][W] += rA * loadW
        if rotary:
            # the spin of the sections: polar inertia rho (I_y + I_z) per length, on the rotations
            R = mixed_mass(space, rotation=True) if space.phi else u["rotary_V"]
            put("Gp1", V, W, s.rho * (s.I_y + s.I_z) * R)
            put("Gp1", W, V, -s.rho * (s.I_y + s.I_z) * R.T)
    mats = {k: sp.csr_matrix((np.concatenate(vals[k]), (np.concatenate(rows[k]), np.concatenate(cols[k]))),
                             shape=(n, n)) if vals[k] else sp.csr_matrix((n, n)) for k in rows}
    dof = model.dof
    G, Kc, Fy, Fz, fc = components.disk_rotating(model.stack, dof, n)
    mats["G1"] = (mats["G1"] + G).tocsr()
    mats["Kc1"] = (mats["Kc1"] + Kc).tocsr()
    mats["Gp1"] = (mats["Gp1"] + components.disk_gyroscopic(model.stack, dof, n)).tocsr()
    vec["Fy"] += Fy
    vec["Fz"] += Fz
    vec["fc1"] += fc
    Kb = model.K_bearing if model.K_bearing is not None else sp.csr_matrix((n, n))
    Cb = model.C_bearing if model.C_bearing is not None else sp.csr_matrix((n, n))
    Kbc = model.K_circulatory if model.K_circulatory is not None else sp.csr_matrix((n, n))
    J = components.lateral_turn(model.spaces, n)
    fu1, fq1 = components.unbalance_loads(model.stack, dof, n)
    return RotorOperators(model.M_full, model.K_full, **mats, **vec, Kb=Kb, Kbc=Kbc, Cb=Cb, CbJ=(Cb @ J).tocsr(),
                          MJ=(model.M_full @ J).tocsr(), KJ=((model.K_full - Kb) @ J).tocsr(), fu1=fu1, fq1=fq1,
                          bearing_change=bearing_change(model, Kb, Kbc, Cb, J) if model.stack.speed_dependent else None)


def mixed_mass(space: SegmentSpace, rotation: bool = False) -> sp.csr_matrix:
    """int N^V N^W dx (rows V, columns W) of the two planes' displacement functions (or with ``rotation`` their
    rotation functions), each plane with its own Phi (:func:`nsfem.fem.timoshenko.element_cross`)."""
    x = space.x - space.x[0]                    # local coordinates, as the unit matrices
    return hermite.assemble_local(x, timoshenko.element_cross(np.diff(x), space.shear("V"), space.shear("W"),
                                                              rotation))


def bearing_change(model: FEModel, Kb, Kbc, Cb, J) -> Callable[[float], tuple]:
    """speed [Hz] -> the changes of the bearings' (K_b, K_c, C_b, C_b J) from the assembled ones (``model``'s
    stack holds the coefficients at the scene's speed) when their tables are read at that speed."""
    n = model.n_full

    def change(speed_hz: float) -> tuple:
        Kb2, Kc2, Cb2 = components.bearing_matrices(model.stack.at_speed(speed_hz), model.dof, n)
        dC = (Cb2 - Cb).tocsr()
        return (Kb2 - Kb).tocsr(), (Kc2 - Kbc).tocsr(), dC, (dC @ J).tocsr()
    return change
