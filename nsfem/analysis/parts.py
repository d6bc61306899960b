"""A stationary state per part: a stator ring as one force and one whirl, a crack as one opening.

A ring of ``facets`` contact points (:mod:`nsfem.contact.ring`) is read by a rotor engineer as one
contact: the resultant force the shaft puts on the ring (the vector sum over its facets of the normal
force lam_N n and the circumferential friction -lam_T t, n = (cos a, sin a) the facet's outward normal,
t = (-sin a, cos a)), the whirl of the shaft centre at the ring (radius and angle of (V, W)), the smallest
facet gap and which facets touch. A crack is its opening (the largest gap over its face points) and the
force its closed faces carry. Angles are measured from +y towards +z in the frame of the coordinates.

>>> import numpy as np
>>> np.degrees(polar(np.array([0.0, -2.0])))[1].round(6).tolist()
-90.0
"""

from __future__ import annotations

import math

import numpy as np

from .reactions import node_lateral


def polar(v: np.ndarray) -> np.ndarray:
    """(radius, angle [rad]) of a vector (y, z)."""
    return np.array([math.hypot(v[0], v[1]), math.atan2(v[1], v[0])])


def facet_forces(st, model) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per stator facet k (index into the contacts): the (normal, friction) forces (y, z) [N] the shaft puts
    on it, the negative of the contact force -lam_N n + lam_circ t on the shaft (eq. 19 and
    :func:`~nsfem.contact.kinematics.slip_rows`' circumferential row t.(V, W))."""
    out = {}
    for k, c in enumerate(model.stack.contacts):
        if c.angle is None:
            continue
        n = np.array([math.cos(c.angle), math.sin(c.angle)])
        t = np.array([-n[1], n[0]])
        names = st.contacts.tangents[k]
        circ = float(st.tangential_force[k][names.index("circumferential")]) if "circumferential" in names else 0.0
        out[k] = (st.normal_force[k] * n, -circ * t)
    return out


def _groups(model, prefix: str) -> dict[str, list[int]]:
    groups: dict[str, list[int]] = {}
    for k, c in enumerate(model.stack.contacts):
        key = c.table_key
        if key.startswith(prefix):
            groups.setdefault(key, []).append(k)
    return groups


def ring_summaries(st, model, q_full: np.ndarray) -> list[dict]:
    """One entry per stator ring: ``{"key", "x_m", "force_N", "force_yz_N", "angle_deg", "normal_N",
    "friction_N", "radius_m", "whirl_yz_m", "whirl_angle_deg", "min_clearance_m", "state", "facets"}``
    (force on the ring; ``normal_N`` and ``friction_N`` the sizes of its normal and friction parts;
    ``facets`` the facet numbers in contact; ``state`` open, stick or slip)."""
    forces = facet_forces(st, model)
    out = []
    for key, ks in _groups(model, "stator.").items():
        c0 = model.stack.contacts[ks[0]]
        N = np.sum([forces[k][0] for k in ks], axis=0)
        T = np.sum([forces[k][1] for k in ks], axis=0)
        F = N + T
        u = node_lateral(model, c0.x, q_full, c0.segments[0])
        (force, angle), (radius, whirl) = polar(F), polar(u)
        closed = [k for k in ks if st.state[k] != "open"]
        states = {st.state[k] for k in closed}
        out.append({"key": key, "x_m": c0.x, "force_N": float(force), "force_yz_N": F.tolist(),
                    "angle_deg": math.degrees(angle) if force > 0 else None,
                    "normal_N": float(math.hypot(*N)), "friction_N": float(math.hypot(*T)),
                    "radius_m": float(radius), "whirl_yz_m": u.tolist(),
                    "whirl_angle_deg": math.degrees(whirl) if radius > 0 else None,
                    "min_clearance_m": float(min(st.gap[k] for k in ks)),
                    "state": "open" if not closed else ("slip" if "slip" in states else "stick"),
                    "facets": [int(model.stack.contacts[k].label.rpartition(".")[2]) for k in closed]})
    return out


def crack_summaries(st, model) -> list[dict]:
    """One entry per crack: ``{"key", "x_m", "opening_m" (the largest gap over its face points), "face_force_N"
    (the normal force its closed points carry), "state"}`` (open, closed, or partly closed)."""
    out = []
    for key, ks in _groups(model, "crack.").items():
        closed = sum(st.state[k] != "open" for k in ks)
        out.append({"key": key, "x_m": model.stack.contacts[ks[0]].x,
                    "opening_m": float(max(st.gap[k] for k in ks)),
                    "face_force_N": float(sum(st.normal_force[k] for k in ks)),
                    "state": "open" if closed == 0 else "closed" if closed == len(ks) else "partly closed"})
    return out


__all__ = ["crack_summaries", "facet_forces", "polar", "ring_summaries"]
