"""Finite-element model of a beam stack: dof numbering, mass and stiffness, constraints T.

Each segment carries three fields in its own scikit-fem bases: U (ElementLineP1/P2) and
V, W (ElementLineHermite: value and slope at every node). The full dof vector stacks,
segment by segment, [U, V, W]. Supports and junctions are eliminated exactly by the
sparse transformation q_full = T q (:mod:`nsfem.fem.constraints`).

>>> from nsfem.scene import load_scene
>>> model = build_model(load_scene(None, ["mesh.elements=20"]))
>>> model.n_full, model.n      # 4 segments; 2 junctions x 2 slaves x 5 dofs and 5 support dofs removed
(200, 175)
>>> bool(abs(model.K - model.K.T).max() == 0.0)
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementLineHermite, ElementLineP1, ElementLineP2, MeshLine, asm

from ..errors import SceneError
from ..mesh import StackMesh, generate, read
from ..stack import BeamStack
from . import components, forms, hermite, timoshenko
from .constraints import constraint_basis, project

if TYPE_CHECKING:
    from ..scene import MeshOptions, Scene

AXIAL_ELEMENTS = {"P1": ElementLineP1, "P2": ElementLineP2}
#: beam theories whose sections carry rotary inertia and the spin's gyroscopic couple
ROTARY_THEORIES = ("rayleigh", "timoshenko")


@dataclass
class SegmentSpace:
    """Bases and global dof indices of one segment's fields."""

    x: np.ndarray  # global node coordinates; the bases use x - x[0]
    axial: Basis
    bending: Basis
    dofs: dict[str, np.ndarray]  # "U", "V", "W" -> global indices in basis order
    unit: dict[str, sp.csr_matrix] = field(default_factory=dict)  # unit-coefficient matrices
    #: Timoshenko's shear parameter Phi per element of the V and W planes (zeros: no shear, Hermite elements)
    phi: dict[str, np.ndarray] = field(default_factory=dict)

    def shear(self, fld: str) -> np.ndarray:
        """Phi per element of bending field V or W (zeros without shear)."""
        return self.phi.get(fld, np.zeros(self.x.size - 1))

    def node(self, x: float) -> int:
        i = int(np.argmin(np.abs(self.x - x)))
        if abs(self.x[i] - x) > 1e-9 * max(1.0, abs(x)):
            raise SceneError("mesh", f"no node at x={x} in a segment spanning [{self.x[0]}, {self.x[-1]}]")
        return i


@dataclass
class FEModel:
    """Assembled beam-stack model: full operators, constraint basis T, constrained M and K."""

    stack: BeamStack
    mesh: StackMesh
    axial: str
    spaces: dict[str, SegmentSpace]
    M_full: sp.csr_matrix
    K_full: sp.csr_matrix
    T: sp.csr_matrix
    M: sp.csr_matrix
    K: sp.csr_matrix
    #: the bearings' part of K_full (symmetric), their cross coupling (skew, circulatory: not in K_full) and
    #: their damping (full coordinates; None without bearings)
    K_bearing: sp.csr_matrix | None = None
    C_bearing: sp.csr_matrix | None = None
    K_circulatory: sp.csr_matrix | None = None

    @property
    def n_full(self) -> int:
        return self.M_full.shape[0]

    @property
    def n(self) -> int:
        """Independent dofs after supports and junctions (the model's ``ndof_full``)."""
        return self.T.shape[1]

    def dof(self, segment: str, name: str, x: float) -> int:
        """Global index of dof ``name`` (U, V, W, V' or W') at node ``x`` of ``segment``."""
        sp_ = self.spaces[segment]
        i = sp_.node(x)
        fld = name.rstrip("'")
        if fld == "U":
            if name != "U":
                raise SceneError("support.fix", "the axial field U has no slope dof")
            return int(sp_.dofs["U"][sp_.axial.nodal_dofs[0, i]])
        slope = 1 if name.endswith("'") else 0
        return int(sp_.dofs[fld][sp_.bending.nodal_dofs[slope, i]])

    def field_dofs(self, fld: str) -> np.ndarray:
        """All global dofs of field U, V or W over every segment."""
        return np.concatenate([s.dofs[fld] for s in self.spaces.values()])

    def constrain(self, C: sp.spmatrix, prefer=None, base=None):
        """base T2 with extra constraint rows C on the full dofs (e.g. closed contacts).

        ``base`` maps the coordinates to full ones (default: T; a reduction's T V). Rows are
        judged for redundancy at their size before projection.
        """
        base = self.T if base is None else base
        C = sp.csr_matrix(C)
        scale = abs(C).max(axis=1).toarray().ravel() * max(float(abs(base).max()), 1.0)
        T2, _ = constraint_basis(sp.csr_matrix(C @ base), base.shape[1], prefer, row_scale=scale)
        out = base @ T2
        return out.tocsr() if sp.issparse(out) else out


def segment_spaces(stack: BeamStack, mesh: StackMesh, axial: str) -> dict[str, SegmentSpace]:
    """Bases, dof numbering and unit matrices for every segment.

    The bending unit matrices are per plane (``mass_V``, ``rotary_V``, ``bend_V``, likewise W): int N_v N_v,
    int N_psi N_psi and the stiffness per E I; without shear (euler-bernoulli, rayleigh) the Hermite
    ``bending_mass``, ``bending_stretch``, ``bending_bend`` for both planes, with Timoshenko's the
    interdependent element of :mod:`nsfem.fem.timoshenko` with the plane's Phi."""
    spaces, offset = {}, 0
    for s in stack.segments:
        x = np.asarray(mesh.nodes[s.name], dtype=float)
        # local coordinates: scikit-fem's Hermite element is built in the mesh's x, and a
        # segment far from the origin would lose digits (measured 1e-4 at x0 = 1000 m)
        m = MeshLine(x - x[0])
        ba = Basis(m, AXIAL_ELEMENTS[axial]())
        bb = Basis(m, ElementLineHermite())
        dofs = {}
        for fld, basis in (("U", ba), ("V", bb), ("W", bb)):
            dofs[fld] = offset + np.arange(basis.N)
            offset += basis.N
        unit = {
            "axial_mass": asm(forms.mass, ba).tocsr(),
            "axial_stretch": asm(forms.stretch, ba).tocsr(),
            # the Hermite integrals in closed form: scikit-fem's quadrature of its Vandermonde-built
            # shape functions carries 1e-11 of round-off that differs between BLAS kernels
            "bending_mass": hermite.assemble(m.p[0], hermite.element_mass),
            "bending_stretch": hermite.assemble(m.p[0], hermite.element_stretch),
            "bending_bend": hermite.assemble(m.p[0], hermite.element_bend),
        }
        phi = {}
        for fld in ("V", "W"):
            if stack.theory == "timoshenko":
                h = np.diff(m.p[0])
                phi[fld] = timoshenko.section_phi(s, h, stack.shear_coefficient)[fld]
                unit[f"mass_{fld}"] = hermite.assemble_local(m.p[0], timoshenko.element_mass(h, phi[fld]))
                unit[f"rotary_{fld}"] = hermite.assemble_local(m.p[0], timoshenko.element_rotary(h, phi[fld]))
                unit[f"bend_{fld}"] = hermite.assemble_local(m.p[0], timoshenko.element_stiffness(h, phi[fld]))
            else:
                unit[f"mass_{fld}"], unit[f"rotary_{fld}"], unit[f"bend_{fld}"] = (
                    unit["bending_mass"], unit["bending_stretch"], unit["bending_bend"])
        spaces[s.name] = SegmentSpace(x, ba, bb, dofs, unit, phi)
    return spaces


def mass_stiffness(stack: BeamStack, spaces: dict[str, SegmentSpace]) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Block-diagonal full mass and stiffness: rhoA, EA, E I_z (V), E I_y (W) per segment (rho I_z, rho I_y
    on the rotations with rotary inertia: rayleigh and timoshenko)."""
    Ms, Ks = [], []
    rotary = stack.theory in ROTARY_THEORIES
    for s in stack.segments:
        u = spaces[s.name].unit
        rA = s.rho * s.area
        mV = rA * u["mass_V"] + (s.rho * s.I_z * u["rotary_V"] if rotary else 0)
        mW = rA * u["mass_W"] + (s.rho * s.I_y * u["rotary_W"] if rotary else 0)
        Ms += [rA * u["axial_mass"], mV, mW]
        Ks += [s.E * s.area * u["axial_stretch"], s.E * s.I_z * u["bend_V"], s.E * s.I_y * u["bend_W"]]
    return sp.block_diag(Ms, format="csr"), sp.block_diag(Ks, format="csr")


def support_and_junction_rows(model_like, stack: BeamStack) -> tuple[sp.csr_matrix, list[int]]:
    """Constraint rows (C q_full = 0) of supports and junctions, with preferred slave dofs."""
    rows, prefer = [], []
    dof = model_like.dof

    def add(entries: dict[int, float], slave: int) -> None:
        rows.append(entries)
        prefer.append(slave)

    for sup in stack.supports:
        for name in sup.fix:
            i = dof(sup.segment, name, sup.x)
            add({i: 1.0}, i)
    for j in stack.junctions:
        m = stack.segment(j.master)
        for sname in j.slaves:
            s = stack.segment(sname)
            for name in ("V", "V'", "W", "W'"):
                a, b = dof(sname, name, j.x), dof(j.master, name, j.x)
                add({a: 1.0, b: -1.0}, a)
            dy, dz = s.offset[0] - m.offset[0], s.offset[1] - m.offset[1]
            us = dof(sname, "U", j.x)
            e = {us: 1.0, dof(j.master, "U", j.x): -1.0}
            for name, c in (("W'", dz), ("V'", dy)):
                if c != 0.0:
                    k = dof(j.master, name, j.x)
                    e[k] = e.get(k, 0.0) + c
            add(e, us)
    for k in stack.cracks:   # a crack's hinge: the right side's U, V, W follow the left's, the slopes are free
        left, right = k.segments
        for name in ("U", "V", "W"):
            a, b = dof(right, name, k.x), dof(left, name, k.x)
            add({a: 1.0, b: -1.0}, a)
    n = model_like.n_full
    C = sp.lil_matrix((len(rows), n))
    for r, entries in enumerate(rows):
        for c, v in entries.items():
            C[r, c] += v
    return C.tocsr(), prefer


class _Numbering:
    """Just enough of FEModel to number dofs before the matrices exist."""

    def __init__(self, spaces, n_full):
        self.spaces, self.n_full = spaces, n_full

    dof = FEModel.dof


def assemble(stack: BeamStack, mesh: StackMesh, axial: str = "P1") -> FEModel:
    """Assemble M, K of a validated stack on a mesh and eliminate supports and junctions.

    M and K are the structure's: the shaft's with the disks' mass and inertia and the bearings'
    stiffness and the open cracks' hinge springs (:mod:`nsfem.fem.components`), so modes and reductions see the rotor as built. K stays
    symmetric: a bearing's cross coupling (skew) is kept apart as ``K_circulatory``."""
    spaces = segment_spaces(stack, mesh, axial)
    M_full, K_full = mass_stiffness(stack, spaces)
    n = M_full.shape[0]
    numbering = _Numbering(spaces, n)
    Kb, Kc, Cb = components.bearing_matrices(stack, numbering.dof, n)
    M_full = (M_full + components.disk_mass(stack, numbering.dof, n)).tocsr()
    K_full = (K_full + Kb + components.crack_stiffness(stack, numbering.dof, n)).tocsr()
    C, prefer = support_and_junction_rows(numbering, stack)
    T, _ = constraint_basis(C, n, prefer)
    return FEModel(stack, mesh, axial, spaces, M_full, K_full, T, project(T, M_full), project(T, K_full), Kb, Cb, Kc)


def build_model(scene: Scene) -> FEModel:
    """Mesh and assemble a scene: its stack with its ``[mesh]`` (:func:`build_stack_model`)."""
    return build_stack_model(scene.stack, scene.mesh_options)


def build_stack_model(stack: BeamStack, options: MeshOptions) -> FEModel:
    """Mesh ``stack`` (generated with ``options.elements`` elements or read from ``options.file``) and
    assemble it with ``options.axial`` for U."""
    mesh = read(options.file, stack) if options.file else generate(stack, options.elements)
    return assemble(stack, mesh, options.axial)
