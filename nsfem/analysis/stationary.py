"""Stationary contact states: LCP (28) under the constant loads (paper section 3.1).

In the rotating frame the constant loads are the centrifugal load Omega^2 f_c1 (it
pushes sub-beams off the axis apart) and the drag of external damping; gravity is
harmonic there and enters only when the scene does not rotate. The stationary state
solves Q q = f0 + J_N lam_N + J_T lam_T with Signorini contact and the paper's
displacement-level friction law (26, 27): tangential displacements start at zero and
grow monotonically, so friction opposes them.

Existence (paper, after eq. 28): a solution is guaranteed when Q is symmetric positive
definite, or when there is no friction and Q is positive definite (its symmetric part).
Otherwise the report says so; Lemke's method then either finds a solution (with its
certificate) or reports why it could not.

>>> from nsfem import build_model, load_scene
>>> scene = load_scene(None, ["mesh.elements=20", "reduction.method=none"])
>>> st = scene_stationary(scene)
>>> st.state[:3], bool(st.gap.min() > 0), st.existence["guaranteed"]
(['open', 'open', 'open'], True, True)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..contact.ring import compliance
from ..contact.set import ContactSet
from ..errors import NsfemError
from ..lcp.builders import stationary_lcp
from ..lcp.pivoting import LCPError, LCPResult
from ..linalg import factorize

if TYPE_CHECKING:
    from ..scene import Damping, Rotation, Scene


@dataclass
class Stationary:
    """A stationary contact state in the coordinates of ``contacts``."""

    q: np.ndarray
    gap: np.ndarray                       # m
    normal_force: np.ndarray              # N
    tangential_force: list[np.ndarray]    # N, components along each contact's tangents
    slip: list[np.ndarray]                # m, tangential displacement per contact
    state: list[str]                      # open | stick | slip per contact
    existence: dict
    lcp: LCPResult
    contacts: ContactSet
    wall_s: float = 0.0
    info: dict = field(default_factory=dict)
    #: the rotor's parts in this state (:func:`rotor_parts`): ``load_N``, ``bearings``, ``supports``,
    #: ``disks``, ``max_deflection``, ``rings``, ``cracks``; empty when not computed
    parts: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        cs = self.contacts
        return {
            "contacts": list(cs.labels), "x_m": [None if math.isnan(v) else float(v) for v in cs.x],
            "gap_m": self.gap.tolist(), "normal_force_N": self.normal_force.tolist(),
            "tangential_force_N": [float(np.linalg.norm(t)) for t in self.tangential_force],
            "tangential_force_components_N": [t.tolist() for t in self.tangential_force],
            "tangent_directions": [list(t) for t in cs.tangents],
            "slip_m": [s.tolist() for s in self.slip], "state": self.state,
            "closed": int(sum(s != "open" for s in self.state)),
            "existence": self.existence,
            "lcp": {"size": int(self.lcp.x.size), "pivots": self.lcp.pivots, "status": self.lcp.status,
                    "residual": self.lcp.residual},
            **self.parts,
        }


def existence(Q, frictionless: bool, asymmetry: str = "external damping adds the circulatory P") -> dict:
    """The paper's existence statement for LCP (28) applied to Q (dense or sparse); ``asymmetry`` names what
    makes Q unsymmetric (:func:`asymmetry_causes`)."""
    Qd = Q
    scale = float(abs(Q).max()) if (sp.issparse(Q) and Q.nnz) or (not sp.issparse(Q) and Q.size) else 1.0
    asym = abs(Q - Q.T).max() if sp.issparse(Q) else np.abs(Q - Q.T).max()
    symmetric = bool(asym <= 1e-12 * max(scale, 1e-300))
    pd = _positive_definite(0.5 * (Qd + Qd.T))
    if symmetric and pd:
        return {"guaranteed": True, "symmetric": True, "positive_definite": True,
                "reason": "Q is symmetric positive definite: a solution exists (paper, after eq. 28)"}
    if frictionless and pd:
        return {"guaranteed": True, "symmetric": symmetric, "positive_definite": True,
                "reason": "no friction and Q positive definite: a solution exists (paper, after eq. 28)"}
    why = []
    if not symmetric:
        why.append(f"Q is not symmetric ({asymmetry})")
    if not pd:
        why.append("Q is not positive definite (the speed lies beyond a divergence speed)")
    if not frictionless:
        why.append("contacts have friction")
    return {"guaranteed": False, "symmetric": symmetric, "positive_definite": pd,
            "reason": "existence not guaranteed: " + "; ".join(why)}


def _positive_definite(H) -> bool:
    """Whether the symmetric H is positive definite (Cholesky, or sparse LDL^T inertia)."""
    n = H.shape[0]
    if n <= 3000 or not sp.issparse(H):
        try:
            np.linalg.cholesky(H.toarray() if sp.issparse(H) else np.asarray(H))
            return True
        except np.linalg.LinAlgError:
            return False
    try:  # symmetric ordering, no pivoting: U's diagonal is D of H = L D L^T (Sylvester)
        lu = spla.splu(sp.csc_matrix(H), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:
        return False
    return bool(np.all(lu.U.diagonal() > 0))


def stationary(Q, f0: np.ndarray | None, contacts: ContactSet, compliance: np.ndarray | None = None,
               asymmetry: str = "external damping adds the circulatory P", **lemke_options) -> Stationary:
    """Solve LCP (28) for the stiffness Q, constant load f0 and ``contacts``; ``compliance`` (m x m) adds the
    contacts' own flexibility to the gaps (an elastic ring, :func:`~nsfem.contact.ring.compliance`): a
    gap g + compliance lam >= 0, so a facet of an elastic ring carries its force at a negative gap.

    Raises :class:`~nsfem.lcp.pivoting.LCPError` with Lemke's diagnosis (and the existence
    caveat) when no solution is found, NsfemError when Q is singular.
    """
    t0 = time.perf_counter()
    cs = contacts
    ex = existence(Q, frictionless=not np.any(cs.r > 0), asymmetry=asymmetry)
    Qf = factorize(Q, "the stiffness Q = K0 + Kc + P",
                   "the structure has rigid-body motion no support restrains, or the speed is a "
                   "divergence speed; a stationary state needs Q to be invertible")
    # a moving surface (a stator's facet) slides: its friction opposes the slip velocity Sq^T q + w of the
    # state, whose direction is taken from the state without contact forces, then from each solution
    # until it agrees (the constant w, Omega times the radius, dominates: one pass in practice)
    moving = [k for k in range(cs.m) if cs.r[k] > 0 and cs.moving[k]]
    q = np.zeros(cs.n) if f0 is None else Qf.solve(f0)
    slide = None
    for _ in range(5):
        rates = {k: cs.slip_rate(k, q, np.zeros(cs.n)) for k in moving}
        # a rate at the round-off of its terms has no direction: that contact's friction is an unknown
        size = {k: float((np.abs(cs.JSq[k]).T @ np.abs(q)).sum() + np.abs(cs.wS[k]).sum()) for k in moving}
        want = {k: -_direction(u) for k, u in rates.items() if _length(u) > 1e-12 * size[k]}
        if slide is not None and want.keys() == slide.keys() and all(np.allclose(slide[k], d) for k, d in want.items()):
            break   # the last solution's friction opposes its slip velocities
        slide = want
        lcp = stationary_lcp(cs, Qf, f0, slide=slide)
        if compliance is not None:
            m = lcp.normal.size
            lcp.A[:m, :m] += compliance[np.ix_(lcp.normal, lcp.normal)]
        res = lcp.solve(**lemke_options)
        if not res.success:
            extra = "" if ex["guaranteed"] else f" ({ex['reason']})"
            raise LCPError(f"stationary LCP (28) with {lcp.size} unknowns: {res.message}{extra}")
        q = lcp.motion(res.x)
        if not moving:
            break
    else:
        raise LCPError("stationary LCP (28): no state whose friction at the moving surfaces opposes their slip "
                       "velocity (its direction changed with each solution)")
    lamN, _, z = lcp.split(res.x)
    gap = cs.gaps(q)
    gap[lamN > 0] = np.where(np.abs(gap[lamN > 0]) < 1e-12 * max(np.abs(lcp.b).max(initial=0.0), 1e-300), 0.0,
                             gap[lamN > 0])
    tang = [np.zeros(len(t)) for t in cs.tangents]
    for k, t in zip(lcp.friction, lcp.tangential(res.x)):
        tang[int(k)] = t
    for j, k in enumerate(lcp.normal):
        if int(k) in slide:
            tang[int(k)] = cs.mu[k] * lamN[j] * slide[int(k)]
    slip = [cs.slip(k, q) for k in range(cs.m)]
    # a contact is closed when it carries force; friction slides when the cone is saturated (z > 0)
    fscale = max(float(lamN.max(initial=0.0)), _closing_force(lcp))
    dscale = max(float(np.abs(lcp.b).max(initial=0.0)), 1e-300)
    closed = lamN > 1e-9 * fscale
    zk = dict(zip((int(k) for k in lcp.friction), z))
    state = ["open" if not closed[k] else ("stick" if cs.r[k] > 0 and k not in slide
                                            and zk.get(k, 0.0) <= 1e-9 * dscale else "slip") for k in range(cs.m)]
    return Stationary(q, gap, lamN.copy(), tang, slip, state, ex, res, cs, time.perf_counter() - t0)


def _length(u: np.ndarray) -> float:
    """|u| without overflowing the squares of huge entries (or underflowing tiny ones)."""
    top = float(np.max(np.abs(u), initial=0.0))
    return top * float(np.linalg.norm(u / top)) if 0.0 < top < math.inf else top


def _direction(u: np.ndarray) -> np.ndarray:
    """u / |u|, scaled first (:func:`_length`)."""
    v = u / np.max(np.abs(u))
    return v / np.linalg.norm(v)


def _closing_force(lcp) -> float:
    """A force scale of the problem: what it takes to cancel the largest free gap."""
    m = lcp.normal.size
    if m == 0:
        return 1e-300
    d = np.diag(lcp.A)[:m]
    d = np.where(d > 0, d, np.inf)
    return float(np.max(np.abs(lcp.b[:m]) / d, initial=1e-300))


def asymmetry_causes(stack, rotation: Rotation, damping: Damping) -> str:
    """What makes the stationary Q of ``nsfem.system.linear_system`` unsymmetric, naming the scene keys: the
    bearings' cross coupling (kyz != kzy), and at speed in the rotating frame external damping (Omega c_e P1)
    and bearing damping (Omega C_b J), in the inertial frame internal damping (-Omega D_i J)."""
    out = [f"{b.label or f'bearing.{i}'}'s cross coupling kyz = {b.K[0][1]:g} != kzy = {b.K[1][0]:g}"
           for i, b in enumerate(stack.bearings) if b.K[0][1] != b.K[1][0]]
    if rotation.speed_hz and rotation.frame == "rotating":
        if damping.external:
            out.append("damping.external adds the circulatory Omega c_e P")
        out += [f"{b.label or f'bearing.{i}'}'s damping, fixed in space, is circulatory seen from the rotating frame"
                for i, b in enumerate(stack.bearings) if any(any(r) for r in b.C)]
    elif rotation.speed_hz and any(damping.rayleigh):
        out.append("damping.rayleigh, turning with the shaft, adds the circulatory -Omega D_i J")
    return "; ".join(out) or "round-off"


def _check_damping(ops, damping: Damping, model) -> None:
    """The damping check of ``nsfem run`` and ``campbell`` (:func:`nsfem.system.check_damping`): damping beyond
    double precision enters Q too (external damping's circulatory part Omega c_e P1, internal damping's in
    the inertial frame) and would otherwise be reported as a singular stiffness."""
    from ..system import check_damping
    from .campbell import DAMPING_CHECK_MAX_DOF, standstill_frequencies

    if (damping.external or any(damping.rayleigh)) and ops.n <= DAMPING_CHECK_MAX_DOF:
        check_damping(damping.rayleigh, standstill_frequencies(ops), damping.external,
                      min(seg.rho * seg.area for seg in model.stack.segments))


def scene_stationary(scene: Scene, model=None, reduction=None) -> Stationary:
    """The stationary state of a scene at its speed, in the scene's reduced coordinates (its model
    and reduction unless given; :func:`rotor_stationary`)."""
    from ..fem.assemble import build_model
    from ..reduce import scene_reduction

    t0 = time.perf_counter()
    model = build_model(scene) if model is None else model
    red = scene_reduction(scene.reduction, model) if reduction is None else reduction
    return rotor_stationary(model, red, scene.rotation, scene.damping, t0)


def rotor_stationary(model, reduction, rotation: Rotation, damping: Damping, t0: float | None = None) -> Stationary:
    """The stationary state of a model with ``[rotation]`` and ``[damping]`` at ``rotation.speed_hz``, in
    ``reduction``'s coordinates; ``wall_s`` counts from ``t0`` (a ``time.perf_counter()``; default: now)."""
    from ..fem.rotating import full_operators
    from ..system import rotor_system

    t0 = time.perf_counter() if t0 is None else t0
    full = full_operators(model)
    ops = full.project(reduction.T)
    _check_damping(ops, damping, model)
    system = rotor_system(ops, rotation, damping)
    system_full = rotor_system(full, rotation, damping)
    from .rigid_motion import rigid_error

    try:
        factorize(system.Q, "Q")
    except NsfemError:  # name the rigid motion that makes it singular, and the key that restrains it
        text = rigid_error(model, system_full.Q)
        if text:
            raise NsfemError(text) from None
    cs = ContactSet.from_model(model, reduction, omega=2.0 * math.pi * rotation.speed_hz, frame=rotation.frame)
    st = stationary(system.Q, system.f0, cs, compliance(model.stack.contacts),
                    asymmetry=asymmetry_causes(model.stack, rotation, damping))
    inertial = rotation.frame == "inertial"
    unbalanced = any(u.magnitude for u in model.stack.unbalances)
    loads = []
    if rotation.speed_hz and not inertial:
        loads.append("centrifugal")
        if unbalanced:
            loads.append("unbalance")
        if damping.external:
            loads.append("external-damping drag")
    elif rotation.gravity:
        loads.append("gravity")
    # Q at rest with the bearings' coefficients of the speed (a table is not read at 0 Hz: it may not reach it, and
    # Q - Q_rest is the speed's forces on the rotor, the bearings' own change with speed being in their reactions)
    rest = (rotor_system(replace(full, bearing_change=None), replace(rotation, speed_hz=0.0), damping)
            if rotation.speed_hz else system_full)
    st.parts = rotor_parts(model, st, system_full, reduction.T, rotation, rest.Q)
    st.wall_s = time.perf_counter() - t0
    st.info = {"speed_hz": rotation.speed_hz, "loads": loads, "ndof_full": model.n, "ndof": reduction.ndof,
               "reduction": reduction.info}
    from .deflection import stationary_warning

    text = stationary_warning(st, model, reduction.T)
    st.info["warnings"] = [text] if text else []
    if rotation.speed_hz and rotation.gravity and not inertial:
        st.info["note"] = ("gravity is harmonic in the rotating frame and is not a stationary load; "
                           "set rotation.speed_hz = 0 for the state at rest under gravity")
    elif rotation.speed_hz and unbalanced and inertial:
        # the rotating frame takes isotropic bearings only (anisotropic ones are refused there)
        st.info["note"] = ("the unbalance is harmonic in the inertial frame and is not a stationary load; " +
                           ("rotation.frame = \"rotating\" makes it one (the bearings are isotropic)"
                            if all(b.isotropic for b in model.stack.bearings) else
                            ("its steady 1x response is `nsfem response` (a harmonic solve)" if not (
                                model.stack.contacts or model.stack.cracks) else
                             "its steady response is the 1x amplitude of the sensors in `nsfem sweep`")))
    return st


def contact_forces_full(model, st: Stationary) -> np.ndarray:
    """The contact forces J_N lam_N + J_S lam_T of a stationary state in full finite-element coordinates."""
    from ..contact.kinematics import gap_jacobian, slip_jacobian
    from ..contact.set import tangent_names

    J, _ = gap_jacobian(model)
    f = np.asarray(J @ st.normal_force).ravel()
    S = slip_jacobian(model).tocsc()
    col = 0
    for k, c in enumerate(model.stack.contacts):
        if c.friction <= 0:
            continue
        for j, name in enumerate(tangent_names(c)):
            if name in st.contacts.tangents[k]:
                lam = st.tangential_force[k][st.contacts.tangents[k].index(name)]
                f += np.asarray(S[:, col + j].toarray()).ravel() * lam
        col += 2
    return f


def full_state(model, Q, loads: np.ndarray) -> np.ndarray:
    """The full model's displacement (full finite-element coordinates) under ``loads`` (full coordinates) with
    its supports and junctions held: q = T (T^T Q T)^-1 T^T loads. Its residual Q q - loads is then exactly
    the constraint forces C^T lam; a reduced state's residual also holds the reduction's error on every dof
    (the shipped crack scene's supports summed to 68.12 N of its 68.40 N weight)."""
    T = model.T
    Qc = sp.csc_matrix(T.T @ Q @ T)
    return np.asarray(T @ factorize(Qc, "Q").solve(np.asarray(T.T @ loads).ravel())).ravel()


def rotor_parts(model, st: Stationary, system, basis, rotation: Rotation, Q_rest=None) -> dict:
    """The parts of a rotor in a stationary state (``system``: the linear system in full coordinates,
    ``basis``: q_full = basis q): the constant load's resultant ``load_N`` [y, z], each bearing's and
    support's force on the shaft, the deflection at each disk and its largest value along the shaft,
    one entry per stator ring and per crack (:mod:`nsfem.analysis.parts`), and ``deflection_load_N``, the
    resultant of the speed's forces on the deflected rotor that Q holds (``Q_rest``: Q at speed 0; in the
    rotating frame the centrifugal force Omega^2 m u, external damping's drag on the whirl), so that
    ``load_N``, it and the reactions (and a ring's force) balance. A bearing's force is -K u of the
    state's u; a support's is the full model's constraint force under the state's loads and contact forces
    (:func:`full_state`), which the reduced state's residual gives only to the reduction's error (amplified:
    21 % on a 4-mode clamped shaft)."""
    from .parts import crack_summaries, ring_summaries
    from .reactions import bearing_reactions, disk_deflections, lateral_total, shaft_deflection, support_reactions

    q = np.asarray(basis @ st.q).ravel()
    f0 = np.zeros(model.n_full) if system.f0 is None else np.asarray(system.f0)
    loads = f0 + contact_forces_full(model, st)
    held = full_state(model, system.Q, loads)
    residual = np.asarray(system.Q @ held).ravel() - loads
    omega = 2.0 * math.pi * rotation.speed_hz
    Rb = bearing_reactions(model, q, omega, rotation.frame)
    Rs = support_reactions(model, residual)
    # Q q - Q_rest q: the speed's terms; those of the bearings (a fixed damper seen from the rotating frame)
    # are in their reactions, the rest are forces on the rotor
    speed_terms = np.zeros(2) if Q_rest is None or not omega else \
        -lateral_total(model, np.asarray((system.Q - Q_rest) @ q).ravel()) - (Rb - bearing_reactions(model, q)).sum(axis=0)
    stack = model.stack
    return {
        "frame": rotation.frame, "load_N": lateral_total(model, f0).tolist(),
        "deflection_load_N": (speed_terms + 0.0).tolist(),
        "bearings": [{"label": b.label or f"bearing.{i}", "x_m": b.x, "reaction_N": r.tolist(),
                      "magnitude_N": float(np.hypot(*r))} for i, (b, r) in enumerate(zip(stack.bearings, Rb))],
        "supports": [{"x_m": s.x, "segment": s.segment, "fix": list(s.fix), "reaction_N": r.tolist(),
                      "magnitude_N": float(np.hypot(*r))} for s, r in zip(stack.supports, Rs)],
        "disks": disk_deflections(model, q), "max_deflection": shaft_deflection(model, q),
        "rings": ring_summaries(st, model, q), "cracks": crack_summaries(st, model),
    }


__all__ = ["Stationary", "contact_forces_full", "existence", "rotor_parts", "rotor_stationary", "scene_stationary",
           "stationary", "NsfemError"]
