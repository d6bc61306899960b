"""Normal contact kinematics: gaps g = J_N^T q_full + j_N (paper eq. 17, 19, 23).

Interface contacts (delaminations): g = W_upper - W_lower at the point (Dirac ansatz,
paper section 2.2) or averaged with a hat weight Lambda_k of unit integral whose support
reaches the neighbouring contact points (eq. 19). Obstacles: g = clearance - n.u at the
centroid of the carrying segment (n one of +-x, +-y, +-z, or at an angle in the y-z plane for a
stator's facet, in the frame of the coordinates). Crack faces: the axial opening -(y dV' + z dW') of a
face point (y, z) from the hinge's centre, d the jump of the slopes across the crack (with Timoshenko's
shear: of the sections' rotations, the second nodal dof, which turn the faces).

Tangential rows and friction cones are built on the same helpers (later issue).

>>> from nsfem.scene import load_scene
>>> from nsfem.fem import build_model
>>> model = build_model(load_scene(None, ["mesh.elements=20"]))
>>> J, j = gap_jacobian(model)
>>> J.shape, float(abs(J).sum()), j.tolist()[:2]
((200, 9), 18.0, [0.0, 0.0])
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import LinearForm, asm

from ..fem import hermite
from ..fem.assemble import FEModel
from ..stack import Contact

_AXIS = {"x": "U", "y": "V", "z": "W"}


def point_row(model: FEModel, segment: str, fld: str, c: Contact) -> dict[int, float]:
    """Weights w with sum_i w_i q_i = field value at the contact (Dirac) or its hat average.

    ``fld`` is U, V, W, or a slope V', W'.
    """
    space = model.spaces[segment]
    if c.weighting == "dirac":
        return {model.dof(segment, fld, c.x): 1.0}
    slope = fld.endswith("'")
    fld = fld.rstrip("'")
    a, b = c.extent
    peak = 2.0 / (b - a)  # unit integral

    def weight(x):
        up = peak * (x - a) / (c.x - a)
        down = peak * (b - x) / (b - c.x)
        return np.where((x >= a) & (x <= b), np.minimum(up, down), 0.0)

    if fld == "U":
        @LinearForm
        def hat(v, w):
            return weight(w.x[0] + space.x[0]) * (v.grad[0] if slope else v)  # bases use local coordinates

        vec = asm(hat, space.axial)
    else:  # closed-form Hermite shape functions, exact quadrature: the hat's kinks are nodes
        vec = hermite.assemble_weighted(space.x, weight, slope, phi=space.shear(fld))
    nz = np.flatnonzero(vec)
    return {int(space.dofs[fld][i]): float(vec[i]) for i in nz}


def contact_row(model: FEModel, c: Contact) -> tuple[dict[int, float], float]:
    """One column of J_N (as a dict) and the constant j_N of a contact."""
    if c.kind == "interface":
        row = point_row(model, c.segments[0], "W", c)
        for i, v in point_row(model, c.segments[1], "W", c).items():
            row[i] = row.get(i, 0.0) - v
        return row, 0.0
    if c.kind == "crack":   # a crack face's point: -(y dV' + z dW'), d = right - left (paper eq. 17 on a hinge)
        (left, right), (ay, az) = c.segments, c.arm
        row = _combine((-ay, point_row(model, right, "V'", c)), (ay, point_row(model, left, "V'", c)),
                       (-az, point_row(model, right, "W'", c)), (az, point_row(model, left, "W'", c)))
        return {i: v for i, v in row.items() if v != 0.0}, 0.0
    if c.angle is not None:   # a stator's facet: n = (cos, sin) in the y-z plane
        cy, sz = float(np.cos(c.angle)), float(np.sin(c.angle))
        row = _combine((-cy, point_row(model, c.segments[0], "V", c)), (-sz, point_row(model, c.segments[0], "W", c)))
        return {i: v for i, v in row.items() if v != 0.0}, c.clearance
    sign = 1.0 if c.normal[0] == "+" else -1.0
    row = {i: -sign * v for i, v in point_row(model, c.segments[0], _AXIS[c.normal[1]], c).items()}
    return row, c.clearance


def _combine(*terms: tuple[float, dict[int, float]]) -> dict[int, float]:
    out: dict[int, float] = {}
    for coef, row in terms:
        for i, v in row.items():
            out[i] = out.get(i, 0.0) + coef * v
    return out


def slip_rows(model: FEModel, c: Contact) -> list[dict[int, float]]:
    """Tangential relative displacements of a contact, one row per tangent direction.

    Interface (design section 3): s_x = (U_u + h_u/2 W_u') - (U_l - h_l/2 W_l'),
    s_y = V_u - V_l. Obstacle: the displacement of the touched surface point
    (u1 = U - eta V' - zeta W', u2 = V, u3 = W) along the two axes normal to n. A stator's facet
    (normal n = (cos a, sin a) in the y-z plane): the circumferential t.(V, W), t = (-sin a, cos a),
    then the axial U - R n.(V', W') of the surface point at radius R (the moving surface's constant
    part of the slip velocity is :func:`surface_velocity`'s).
    """
    pr = lambda seg, f: point_row(model, seg, f, c)  # noqa: E731
    if c.kind == "crack":
        raise ValueError(f"{c.label}: a crack's faces cannot slide (the hinge shares their displacements)")
    if c.kind == "interface":
        up, lo = c.segments
        hu, hl = model.stack.segment(up).height, model.stack.segment(lo).height
        sx = _combine((1.0, pr(up, "U")), (hu / 2, pr(up, "W'")), (-1.0, pr(lo, "U")), (hl / 2, pr(lo, "W'")))
        return [sx, _combine((1.0, pr(up, "V")), (-1.0, pr(lo, "V")))]
    if c.angle is not None:   # a stator's facet: the circumferential slip, then the axial one
        seg, cy, sz = c.segments[0], float(np.cos(c.angle)), float(np.sin(c.angle))
        circ = _combine((-sz, pr(seg, "V")), (cy, pr(seg, "W")))
        axial = _combine((1.0, pr(seg, "U")), (-c.radius * cy, pr(seg, "V'")), (-c.radius * sz, pr(seg, "W'")))
        return [circ, axial]
    seg = model.stack.segment(c.segments[0])
    sign = 1.0 if c.normal[0] == "+" else -1.0
    axis = c.normal[1]
    rows = []
    for t in "xyz":
        if t == axis:
            continue
        if t == "x" and axis == "z":  # surface at zeta = sign h/2
            rows.append(_combine((1.0, pr(seg.name, "U")), (-sign * seg.height / 2, pr(seg.name, "W'"))))
        elif t == "x" and axis == "y":  # surface at eta = sign b/2
            rows.append(_combine((1.0, pr(seg.name, "U")), (-sign * seg.width / 2, pr(seg.name, "V'"))))
        else:
            rows.append(pr(seg.name, _AXIS[t]))
    return rows


def slip_jacobian(model: FEModel, contacts=None) -> sp.csr_matrix:
    """Tangential slip rows of every contact with friction (mu > 0), as columns (n_full x 2 m_f)."""
    contacts = [c for c in (model.stack.contacts if contacts is None else contacts) if c.friction > 0]
    rows = [r for c in contacts for r in slip_rows(model, c)]
    return _columns(rows, model.n_full)


def _columns(rows: list[dict[int, float]], n: int) -> sp.csr_matrix:
    J = sp.lil_matrix((n, len(rows)))
    for k, row in enumerate(rows):
        for i, v in row.items():
            J[i, k] = v
    return J.tocsr()


def gap_jacobian(model: FEModel, contacts=None) -> tuple[sp.csr_matrix, np.ndarray]:
    """J_N (n_full x m) and j_N (m,) of the stack's contacts (or of ``contacts``)."""
    contacts = model.stack.contacts if contacts is None else contacts
    J = sp.lil_matrix((model.n_full, len(contacts)))
    j = np.zeros(len(contacts))
    for k, c in enumerate(contacts):
        row, j[k] = contact_row(model, c)
        for i, v in row.items():
            J[i, k] = v
    return J.tocsr(), j
