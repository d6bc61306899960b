"""The range of the linear model: deflections the small-deflection theory of eq. (22) can describe.

The beam model is linear in the displacements: it neglects the membrane (stretching) forces a
deflection w brings once the beam is held axially (the sub-beams of a delamination are, by the
junctions at its ends). For a beam held at both ends the neglected stiffening raises a
frequency by sqrt(1 + 3/16 (w/r)^2) - 1 with r = h / sqrt(12) the radius of gyration
(Woinowsky-Krieger 1950): 4 % at w = 0.19 h (the shipped scene's lower sub-beam), 10 % at
w = 0.3 h, 80 % at w = h. :data:`DEFLECTION_FRACTION` warns at 10 %. A gap wider than the
thinnest section leaves the contact kinematics of eq. (19) (faces that stay parallel and
opposite) as well.

>>> print(linear_range_warning([("shaft", 1.5, 0.03, 0.02)], max_gap=None))  # doctest: +NORMALIZE_WHITESPACE
the deflection leaves the range of the linear (small-deflection) model of eq. (22): shaft deflects 0.03 m
laterally, 1.5 times its 0.02 m section (beyond 0.3 of it the neglected stretching shifts frequencies by more
than 10 %); the numbers are the linear model's, not the structure's
>>> linear_range_warning([("shaft", 0.05, 0.001, 0.02)], max_gap=0.001, min_height=0.02) is None
True
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np

#: Warn above this deflection, as a fraction of the section size in its direction: the neglected
#: membrane stiffening then shifts frequencies by 10 % (module docstring).
DEFLECTION_FRACTION = 0.3
#: Output samples processed at once when measuring a long result's deflection.
CHUNK = 4096


def stiffening(fraction: float) -> float:
    """Relative frequency rise sqrt(1 + 3/16 (w/r)^2) - 1 neglected at deflection w = fraction h.

    >>> round(stiffening(0.3), 3)
    0.097
    """
    return math.sqrt(1.0 + 3.0 / 16.0 * 12.0 * fraction**2) - 1.0


def lateral_deflection(model, basis, q: np.ndarray) -> list[tuple[str, float, float, float]]:
    """Per segment (name, largest deflection / section size, that deflection [m], that size [m])
    over all nodes and all columns of ``q`` (reduced coordinates, (n,) or (n, K); q_full = basis q):
    W is measured against the section height, V against its width, whichever is larger."""
    q = np.asarray(q, dtype=float)
    q = q[:, None] if q.ndim == 1 else q
    segs = {s.name: s for s in model.stack.segments}
    out = []
    for name, space in model.spaces.items():
        nod = space.bending.nodal_dofs[0]
        rows = np.concatenate([space.dofs["V"][nod], space.dofs["W"][nod]])
        B = basis[rows]
        B = np.asarray(B.todense() if hasattr(B, "todense") else B)
        k = nod.size
        wv, ww = 0.0, 0.0
        for j in range(0, q.shape[1], CHUNK):
            u = np.abs(B @ q[:, j:j + CHUNK])
            wv = max(wv, float(np.max(u[:k], initial=0.0)))
            ww = max(ww, float(np.max(u[k:], initial=0.0)))
        s = segs[name]
        out.append(max((ww / s.height, ww, s.height), (wv / s.width, wv, s.width)))
        out[-1] = (name, *out[-1])
    return out


def linear_range_warning(deflections: Iterable[tuple[str, float, float, float]], max_gap: float | None,
                         min_height: float | None = None) -> str | None:
    """The warning text when a deflection or a gap leaves the linear model's range, else None.

    ``deflections``: (segment, deflection / section size, deflection [m], size [m]) as from
    :func:`lateral_deflection`; ``max_gap``: the widest contact gap [m]; ``min_height``: the
    thinnest section [m] (no gap check without it).
    """
    parts = []
    worst = max(deflections, key=lambda r: r[1], default=None)
    if worst is not None and worst[1] > DEFLECTION_FRACTION:
        parts.append(f"{worst[0]} deflects {worst[2]:.3g} m laterally, {worst[1]:.3g} times its {worst[3]:.3g} m "
                     f"section (beyond {DEFLECTION_FRACTION:g} of it the neglected stretching shifts frequencies "
                     f"by more than {100 * stiffening(DEFLECTION_FRACTION):.0f} %)")
    if max_gap is not None and min_height is not None and max_gap > min_height:
        parts.append(f"a contact gap opens to {max_gap:.3g} m, wider than the thinnest section ({min_height:.3g} m)")
    if not parts:
        return None
    return ("the deflection leaves the range of the linear (small-deflection) model of eq. (22): "
            + "; ".join(parts) + "; the numbers are the linear model's, not the structure's")


def min_section(stack) -> float:
    """The smallest section height or width of a stack [m]."""
    return min(min(s.height, s.width) for s in stack.segments)


def result_warning(result, model, basis) -> str | None:
    """:func:`linear_range_warning` and :func:`penetration_warning` of a transient Result (all output times)."""
    if result.t.size == 0 or result.q.size == 0:
        return None
    gap = float(result.gap.max()) if result.gap.size else None
    texts = [linear_range_warning(lateral_deflection(model, basis, result.q), gap, min_section(model.stack)),
             penetration_warning(result, model.stack)]
    return "; ".join(t for t in texts if t) or None


#: Warn when a rigid stop with a clearance (an obstacle, a stator's facet) is penetrated deeper than this
#: fraction of its own clearance: a penalty spring lets 1 / (1 + factor) of the contact-free motion through
#: (1 % at the default factor 100), moreau's steps O(h) of the approach speed; beyond 10 % the stop no longer
#: holds the motion it is meant to. (Contacts without a clearance, delamination interfaces and crack faces,
#: have no such scale: their gaps are the motion itself.)
PENETRATION_FRACTION = 0.1


def penetration_warning(result, stack) -> str | None:
    """The warning text when one of a run's rigid stops with a clearance (not elastic rings, which carry force
    at a negative gap) was penetrated deeper than :data:`PENETRATION_FRACTION` of its own clearance (a stop
    far from the shaft is not judged by a near one's), else None; it names the stop penetrated deepest
    relative to its clearance."""
    labels = list(result.info.get("contacts", ()))
    gap = np.asarray(result.gap)
    stops = {c.label: c.clearance for c in stack.contacts if c.stiffness == 0.0 and c.clearance > 0.0}
    if gap.size == 0 or len(labels) != gap.shape[0]:
        return None
    rows = [i for i, lab in enumerate(labels) if lab in stops]
    if not rows:
        return None
    clearance = np.array([stops[labels[i]] for i in rows])
    depth = np.maximum(-gap[rows].min(axis=1), 0.0)
    k = int(np.argmax(depth / clearance))
    if not depth[k] > PENETRATION_FRACTION * clearance[k]:
        return None
    remedy = {"penalty": "the penalty spring is too soft for these contacts: raise simulation.penalty_factor (or "
                         "simulation.penalty_stiffness)",
              "moreau": "moreau's step is too coarse for these approach speeds: lower simulation.moreau_step"}
    return (f"the contacts were penetrated {depth[k]:.3g} m deep at {labels[rows[k]]}, more than "
            f"{PENETRATION_FRACTION:g} of its clearance {clearance[k]:.3g} m: "
            f"{remedy.get(result.method, 'the contact constraint was not held')}; the motion beyond the contact is "
            "the model's, not the structure's")


def stationary_warning(st, model, basis) -> str | None:
    """:func:`linear_range_warning` of a stationary state."""
    gap = float(np.max(st.gap)) if np.size(st.gap) else None
    return linear_range_warning(lateral_deflection(model, basis, st.q), gap, min_section(model.stack))
