"""Round rigid stator rings in the exact method: a polygon that turns with the contact point.

A rigid ``[[stator]]`` is the polygon of F facets tangent to the clearance circle (radius c): facet k
has the normal n_k = (cos, sin)(theta_k) and the gap c - n_k . u, u = P q the shaft's centre at the
ring. On a fixed polygon a rotor sliding round the ring meets a corner every 2 pi / F, and under load
comes to rest at one. With ``shape = "round"`` the whole polygon turns by an angle alpha, chosen at
events, so that the facet the rotor slides on stays tangent to the circle near the contact point:

- while facet k alone is closed (tangent at phi), two event rows keep the contact point's angle psi in
  a wedge [phi + lo, phi + hi] (:func:`wedge_rows`); the ring's other gap rows are left out meanwhile
  (the wedge stays narrower than pi / F: none of them can close first);
- at an edge (``round_turn``), the polygon turns to put facet k on a tangent through u to a circle of
  radius between c and its distance c', ahead of u (``mirror``: the gap stays 0, c' returns towards c);
  the velocity's normal part into the new facet, about 2 delta times the sliding speed, goes in a
  plastic impact (what curving a path costs on a polygon of pi / delta facets);
- when the point comes back through the edge it has just crossed, the facet is put tangent at the
  point, through it (distance |u|), and delta is halved (``return``): a rotor settling on the ring
  ends turning a wedge of delta_0 / 1024 about its rest point, a few events per revolution;
- a closure is on the polygon's facet as before (the wedge conformed to the point, :func:`conform`);
  an open ring returns to the scene's polygon once the rotor is inside it by a margin (:func:`relax`).

Roundness error: a closed point lies within c' / cos(w) of the axis (w the wedge's half-width), an open
one within c' / cos(pi / F); the run books the largest of each (``radius_error_max_m``,
``open_radius_error_max_m``). c' grows only at returns, by 1 / cos of a halving wedge: over one settling
c' <= c exp(2 w_0^2 / 3), w_0 = pi / F (docs/theory.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..contact.set import ContactSet

#: delta_0 [rad]: the largest angle between the contact point and its facet's tangent point; the ring's
#: radius within c (1 / cos(delta_0) - 1) = 2.0e-4 c
DELTA = 2e-2
#: mirrors in one direction after which the wedge widens again (a slide on, not a settling)
WIDEN = 4
#: the smallest delta after halvings [rad]
DELTA_MIN = DELTA / 1024
#: a facet's share of a ring's force below this fraction of it is the 2 x 2 split's round-off (polygon_outputs)
ROUND_OFF = 1e-12


@dataclass
class RoundRing:
    """One rigid stator ring of a contact set: its facets' indices (in facet order), theta_k, P (2 x n),
    the clearance c, and the slip's scale parts (JS column = a P^T t_k, JSq column = s J_N column); the
    state: the turn alpha, the facets' distance c' and delta, the direction of the last mirror."""

    label: str
    facets: tuple[int, ...]
    angles: np.ndarray
    P: np.ndarray
    clearance: float
    slip_scale: float
    drift_scale: float
    alpha: float = 0.0
    distance: float = 0.0
    delta: float = DELTA
    last: int = 0
    run: int = 0
    lo: float = -DELTA
    hi: float = DELTA
    #: the facet (index into ``facets``) the wedge [lo, hi] is about
    k: int | None = None
    history: dict = field(default_factory=lambda: {"closures": 0, "mirrors": 0, "returns": 0,
                                                   "radius_error_max_m": 0.0, "open_radius_error_max_m": 0.0})

    def __post_init__(self):
        if not self.distance:
            self.distance = self.clearance

    def phi(self, k: int) -> float:
        """The tangent angle of facet ``k`` (an index into :attr:`facets`) now."""
        return float(self.angles[k]) + self.alpha


    def centre(self, q: np.ndarray) -> np.ndarray:
        return self.P @ q

    def signature(self) -> tuple[float, float]:
        return (self.alpha, self.distance)


def round_rings(cs: ContactSet, labels=(), delta: float = DELTA) -> tuple[RoundRing, ...]:
    """The rigid stator rings named in ``labels`` (``stator.<i>``) of a contact set (contacts labelled
    ``stator.<i>.<k>``, k = 0 .. F - 1, tangents circumferential or frictionless), with their facets' geometry
    recovered from J_N: J_N[:, k] = -P^T n_k."""
    groups: dict[str, list[tuple[int, int]]] = {}
    for j, label in enumerate(cs.labels or ()):
        parts = label.split(".")
        if len(parts) == 3 and parts[0] == "stator" and parts[2].isdigit() and ".".join(parts[:2]) in labels \
                and (not cs.tangents[j] or cs.tangents[j][0] == "circumferential"):
            groups.setdefault(".".join(parts[:2]), []).append((int(parts[2]), j))
    out = []
    for label, members in groups.items():
        members.sort()
        F = len(members)
        if F < 3 or [k for k, _ in members] != list(range(F)):
            continue
        idx = tuple(j for _, j in members)
        angles = 2.0 * math.pi * np.arange(F) / F
        normals = np.column_stack([np.cos(angles), np.sin(angles)])
        JN = cs.JN[:, list(idx)]
        P = -np.linalg.pinv(normals) @ JN.T
        if not np.allclose(-(P.T @ normals.T), JN, rtol=0.0, atol=1e-9 * max(np.abs(JN).max(), 1e-300)):
            continue   # not a ring of one centre (a segment of other stops)
        c = float(cs.jN[idx[0]])
        j0 = idx[0]
        t0 = P.T @ np.array([-normals[0, 1], normals[0, 0]])
        slip = drift = 0.0
        if cs.JS[j0].shape[1]:
            slip = float(cs.JS[j0][:, 0] @ t0 / (t0 @ t0))
            drift = float(cs.JSq[j0][:, 0] @ JN[:, 0] / (JN[:, 0] @ JN[:, 0]))
        out.append(RoundRing(label, idx, angles, P, c, slip, drift, delta=min(delta, 0.5 * math.pi / F)))
    return tuple(out)


def turned(cs: ContactSet, rings) -> ContactSet:
    """``cs`` with each ring's facets turned by its alpha at its distance c'."""
    if not any(r.alpha or r.distance != r.clearance for r in rings):
        return cs
    JN, jN = cs.JN.copy(), cs.jN.copy()
    JS, JSq = list(cs.JS), list(cs.JSq)
    for r in rings:
        a = r.angles + r.alpha
        idx = list(r.facets)
        cols = -(r.P.T @ np.vstack([np.cos(a), np.sin(a)]))          # -P^T n_k
        JN[:, idx] = cols
        jN[idx] = r.distance
        if r.slip_scale:
            slips = r.slip_scale * (r.P.T @ np.vstack([-np.sin(a), np.cos(a)]))   # a P^T t_k
            for k, j in enumerate(idx):
                if JS[j].shape[1]:
                    JS[j] = slips[:, k:k + 1]
                    JSq[j] = r.drift_scale * cols[:, k:k + 1]
    out = ContactSet(JN, jN, cs.mu, cs.eps, tuple(JS), cs.r, cs.labels, cs.tangents, cs.x, tuple(JSq), cs.wS)
    out.__dict__["moving"] = cs.moving   # the surfaces move as before (the turn keeps J_Sq's zeros)
    return out


def wedge_rows(rings, mode, Pq: np.ndarray, add) -> None:
    """Per ring with exactly one closed facet k (tangent at phi): the contact point's angle psi within
    [phi + lo, phi + hi], t(phi + lo) . u >= 0 and -t(phi + hi) . u >= 0 (t(a) = (-sin a, cos a):
    t(a) . u = |u| sin(psi - a)); ``round_turn`` rows with detail (ring, -1 or +1)."""
    closed = set(mode.closed)
    for i, r in enumerate(rings):
        on = [k for k, j in enumerate(r.facets) if j in closed]
        if len(on) != 1:
            continue
        k = on[0]
        U = r.P @ Pq
        a, b = r.phi(k) + r.lo, r.phi(k) + r.hi
        add(-math.sin(a) * U[0] + math.cos(a) * U[1], "round_turn", r.facets[k], (i, -1))
        add(math.sin(b) * U[0] - math.cos(b) * U[1], "round_turn", r.facets[k], (i, 1))


def _width(ring: RoundRing) -> float:
    return min(DELTA, 0.5 * math.pi / len(ring.facets))


def _tangent(ring: RoundRing, k: int, u: np.ndarray, d: int, keep: float | None = None) -> None:
    """Put facet ``k`` on a tangent through u that touches a circle of radius rho ahead of u in the direction
    d, with the wedge from u (its trailing edge) to delta beyond the tangent point: rho = c, or, given
    ``keep`` (the angle from u to the tangent point of the circle of radius c' it is on), the circle whose
    tangent point lies at most delta further than that (c' shrinks back to c over a slide)."""
    r = float(math.hypot(u[0], u[1]))
    psi = math.atan2(u[1], u[0])
    beta = math.acos(min(1.0, ring.clearance / r)) if r > 0.0 else 0.0
    if keep is not None:
        beta = min(beta, abs(keep) + ring.delta)
    ring.distance = max(r * math.cos(beta), ring.clearance)
    ring.alpha = math.remainder(psi + d * beta - float(ring.angles[k]), 2.0 * math.pi)
    trail = max(beta, ring.delta)
    ring.lo, ring.hi = (-trail, ring.delta) if d > 0 else (-ring.delta, trail)
    ring.k = k
    _record(ring)


def _record(ring: RoundRing) -> None:
    """Book the largest distance from the circle of radius c that the ring's model allows now: closed, the
    wedge's c' / cos(w) - c; open, the turned polygon's c' / cos(pi / F) - c."""
    err = ring.distance / math.cos(max(-ring.lo, ring.hi)) - ring.clearance
    ring.history["radius_error_max_m"] = max(ring.history["radius_error_max_m"], err)
    err = ring.distance / math.cos(math.pi / len(ring.facets)) - ring.clearance
    ring.history["open_radius_error_max_m"] = max(ring.history.get("open_radius_error_max_m", 0.0), err)


def conform(rings, closed, q: np.ndarray) -> None:
    """After an event: a ring with one closed facet whose wedge is not about it, or does not hold the contact
    point (the facet left closed after a corner of the polygon), gets the wedge from its tangent point to the
    point (at least +-delta)."""
    closed = set(closed)
    for r in rings:
        on = [k for k, j in enumerate(r.facets) if j in closed]
        if len(on) != 1:
            continue
        k = on[0]
        u = r.P @ q
        rel = math.remainder(math.atan2(u[1], u[0]) - r.phi(k), 2.0 * math.pi)
        slack = 1e-9 * max(r.hi - r.lo, r.delta)   # the turn's own round-off puts u on its wedge's edge
        if r.k == k and r.lo - slack <= rel <= r.hi + slack:
            continue
        same = r.k == k   # (else the old wedge is about another facet: it starts afresh at +-delta)
        if not same:
            r.k, r.last, r.run = k, 0, 0
        r.lo, r.hi = min(r.lo if same else -r.delta, rel), max(r.hi if same else r.delta, rel)
        _record(r)


def turn(ring: RoundRing, k: int, q: np.ndarray, d: int) -> None:
    """Turn ``ring`` at a ``round_turn`` event of its closed facet ``k`` (index into its facets) at q, the
    contact point at the wedge's edge d (+1: ahead): on to the next tangent, or re-centre on a return
    (module docstring)."""
    u = ring.P @ q
    if d == -ring.last:   # back through the edge just crossed: tangent at the point, through it
        psi = math.atan2(u[1], u[0])
        ring.alpha = math.remainder(psi - float(ring.angles[k]), 2.0 * math.pi)
        ring.distance = max(float(math.hypot(u[0], u[1])), ring.clearance)
        ring.delta = max(ring.delta / 2.0, DELTA_MIN)
        ring.lo, ring.hi = -ring.delta, ring.delta
        ring.last = ring.run = 0
        ring.k = k
        ring.history["returns"] += 1
        _record(ring)
        return
    ring.run = ring.run + 1 if d == ring.last else 1
    if ring.run > WIDEN:   # a slide on through several wedges: the wedge widens again
        ring.delta = min(2.0 * ring.delta, _width(ring))
    ring.last = d
    ring.history["mirrors"] += 1
    _tangent(ring, k, u, d, ring.hi if d > 0 else ring.lo)


def close(ring: RoundRing, k: int, q: np.ndarray, v: np.ndarray) -> None:
    """At a closure on facet ``k`` alone (the centre on the polygon, within c (1 / cos(pi / F) - 1) outside
    the circle): the facet on the tangent to the circle through the point, ahead of it in the direction
    the centre turns."""
    u, du = ring.P @ q, ring.P @ v
    d = 1 if u[0] * du[1] - u[1] * du[0] >= 0.0 else -1
    ring.delta, ring.run, ring.last = _width(ring), 0, d
    ring.history["closures"] += 1
    _tangent(ring, k, u, d)


def relax(rings, closed, touching, q: np.ndarray) -> bool:
    """Return an open ring to the scene's polygon where the rotor is inside it by at least the distance the
    ring had beyond c and the polygon's own distance from the circle (its configurations are met again; not
    at an event where one of its facets closes or is closed). True when some ring changed."""
    changed = False
    closed = set(closed)
    for r in rings:
        if (r.distance == r.clearance and not r.alpha) or any(j in closed for j in r.facets) \
                or any(j in touching for j in r.facets):
            continue
        u = r.P @ q
        reach = float(np.max(np.cos(r.angles) * u[0] + np.sin(r.angles) * u[1]))   # on the scene's polygon
        margin = max(r.distance - r.clearance, r.clearance * (1.0 / math.cos(math.pi / len(r.facets)) - 1.0))
        if reach <= r.clearance - margin:
            r.alpha, r.distance, r.delta, r.last, r.run = 0.0, r.clearance, _width(r), 0, 0
            r.lo, r.hi, r.k = -r.delta, r.delta, None
            changed = True
    return changed



def polygon_outputs(rings, polygon: ContactSet, q: np.ndarray, gap: np.ndarray, normal: np.ndarray,
                    tangential: np.ndarray, state: np.ndarray) -> None:
    """A round ring's outputs on the scene's polygon, in place (columns of states q (n, t)): each facet's gap
    from that polygon, and the ring's normal force N = sum_k lam_k n(phi_k) and friction sum_k f_k t(phi_k)
    split onto the two facets i, i + 1 around N's direction (N = a n_i + b n_i+1 with a, b >= 0; the friction
    R N-like, f t(phi) = R (f n(phi)), splits with the same coordinates), so that their resultant is the
    ring's and every facet keeps its angle 2 pi k / F."""
    for r in rings:
        idx = list(r.facets)
        F = len(idx)
        gap[idx] = polygon.gaps(q)[idx]
        a = r.angles + r.alpha
        n = np.vstack([np.cos(a), np.sin(a)])                       # 2 x F, the turned facets' normals
        N = n @ normal[idx]                                         # 2 x t
        f = n @ tangential[idx, 0]                                  # R^T of the friction vector
        st = state[idx].max(axis=0)
        normal[idx], tangential[idx], state[idx] = 0.0, 0.0, 0
        cols = np.flatnonzero(np.any(N != 0.0, axis=0) | np.any(f != 0.0, axis=0))
        if not cols.size:
            continue
        Nc, fc = N[:, cols], f[:, cols]
        w = np.where(np.any(Nc != 0.0, axis=0), Nc, fc)
        i = np.floor(np.arctan2(w[1], w[0]) / (2.0 * math.pi / F)).astype(int) % F
        pair = np.array([i, (i + 1) % F])                                   # 2 x columns
        G = np.empty((cols.size, 2, 2))
        G[:, 0], G[:, 1] = np.cos(r.angles[pair]).T, np.sin(r.angles[pair]).T
        lam = np.linalg.solve(G, Nc.T[:, :, None])[:, :, 0].T              # 2 x columns
        fr = np.linalg.solve(G, fc.T[:, :, None])[:, :, 0].T
        # a force along one facet's normal is that facet's alone: the solve leaves the other round-off
        # (cond(G) eps |N| <= 3.6e-14 |N| at F = 1024), no force on an open facet
        lam[np.abs(lam) <= ROUND_OFF * np.hypot(Nc[0], Nc[1])] = 0.0
        fr[np.abs(fr) <= ROUND_OFF * np.hypot(fc[0], fc[1])] = 0.0
        on = (lam != 0.0) | (fr != 0.0)
        for side in range(2):
            c = np.asarray(idx)[pair[side]]
            normal[c, cols], tangential[c, 0, cols] = lam[side], fr[side]
            state[c, cols] = np.where(on[side], st[cols], 0)
