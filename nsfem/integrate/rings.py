"""Elastic rings in the event-driven loop: their event rows and their state across events.

A ring (:mod:`nsfem.contact.ring`) is clear (its centre inside the polygon), engaged with a law (a
region and the case of the cone projection: which facets push, ``Mode.ring``) or latent in a region
(beyond the polygon with the force released, ``Mode.latent``). Its event rows, each valid while >= 0:

- ``ring_engage``: clear, per facet k the distance c - n_k . u to the facet's line; latent or engaged,
  a row of :meth:`Ring.switches` to a law with more facets (a facet's force returns);
- ``ring_release``: engaged, a row of :meth:`Ring.switches` to fewer facets (a facet's force would
  pull: its coordinate of X leaves the cone);
- ``ring_exit``: engaged or latent, the region's boundaries (to a neighbouring region, or inside);
- ``ring_turn``: engaged with friction, s times the slip velocity (it stops: the shaft would roll on
  the ring, which the event-driven methods do not hold).

Without a damper X = k_s d lies in the cone: the exits alone change the law. A row's contact is m + i
(m rigid contacts, ring i), so that rows, events and the guard name rings.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..contact.ring import ROT, Ring
from ..errors import NsfemError
from .configuration import Mode


def ring_rows(phase, mode: Mode, rings, m: int, add) -> None:
    """Add the rings' event rows of a phase (``add(row, kind, contact, detail)``)."""
    if not rings:
        return
    Pq, Pv = phase.q_map(), phase.v_map()
    const = 2 * phase.config.r
    engaged = {i: (law, s) for i, law, s in mode.ring}
    latent = dict(mode.latent)
    for i, ring in enumerate(rings):
        U, dU = ring.P @ Pq, ring.P @ Pv
        if i in engaged:
            law, s = engaged[i]
            reg = ring.place(law)
            _switches(ring, reg, law, Pq, Pv, const, add, m + i, i)
            _exits(ring, reg, U, const, add, m + i, i)
            if ring.friction and s:
                nu = ring.parts(law)[2]
                rate = (ROT @ nu) @ dU + ring.frame_spin * (nu @ U)
                rate[const] += ring.surface_speed
                add(s * rate, "ring_turn", m + i, (i, law))
        elif i in latent:
            reg = latent[i]
            _switches(ring, reg, None, Pq, Pv, const, add, m + i, i)
            _exits(ring, reg, U, const, add, m + i, i)
        else:
            for k, n in enumerate(ring.normals):
                row = -(n @ U)
                row[const] += ring.clearance
                add(row, "ring_engage", m + i, (i, None, k))


def _switches(ring: Ring, reg: int, law: int | None, Pq, Pv, const: int, add, contact: int, i: int) -> None:
    """The rows w . X of the cone projection's cases next to ``law`` on region ``reg`` (detail (i, law, next))."""
    if not ring.damping:
        return
    X = ring.force_rows(reg, Pq, Pv, const, damper=np.eye(2))
    facets = 0 if law is None else len(ring.pushing(law))
    for w, nxt in ring.switches(reg, law):
        kind = "ring_release" if nxt is None or len(ring.pushing(nxt)) < facets else "ring_engage"
        add(w @ X, kind, contact, (i, law, nxt))


def _exits(ring: Ring, reg: int, U: np.ndarray, const: int, add, contact: int, i: int) -> None:
    for g, g0, nxt in ring.boundaries(reg):
        row = g @ U
        row[const] += g0
        add(row, "ring_exit", contact, (i, reg, nxt))


def _sign(ring: Ring, reg: int, u: np.ndarray, du: np.ndarray, t: float) -> int:
    """The slip's sign s in a region (0 without friction); a slip at rest is the rolling the event-driven
    methods do not hold."""
    if not ring.friction:
        return 0
    rate = float(ring.slip_rate(reg, u, du))
    scale = abs(ring.surface_speed) + float(np.abs(du).sum() + abs(ring.frame_spin) * np.abs(u).sum())
    if abs(rate) <= 1e-9 * scale:
        raise rolling(ring, t)
    return 1 if rate > 0 else -1


def rolling(ring: Ring, t: float) -> NsfemError:
    return NsfemError(f"{ring.label}: the shaft surface would roll on the elastic ring at t = {t:.9g} s (its slip "
                      "past the ring stops); the event-driven methods hold friction as sliding only there: run this "
                      "scene with simulation.method = \"moreau\"")


def initial_rings(rings, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> tuple[tuple, tuple]:
    """(ring, latent) of ``Mode`` from a state: engaged with the law of proj_K (X) beyond the polygon."""
    eng, lat = [], []
    for i, ring in enumerate(rings):
        u, du = ring.P @ q, ring.P @ v
        reg = ring.region(u)
        if reg is not None:
            _place(eng, lat, ring, i, reg, ring.law(reg, u, du), u, du, t)
    return tuple(sorted(eng)), tuple(sorted(lat))


def _place(eng: list, lat: list, ring: Ring, i: int, reg: int, law: int | None, u, du, t: float) -> None:
    if law is None:
        lat.append((i, reg))
    else:
        eng.append((i, law, _sign(ring, law, u, du, t)))


def after_event(rings, mode: Mode, fired: list, q: np.ndarray, v: np.ndarray, t: float) -> tuple[tuple, tuple]:
    """(ring, latent) after the ring rows ``fired`` ((kind, detail) pairs) at t, from ``mode``'s: a region
    change reads the law in the new region (X's cone changes with it), a lone switch takes its case, two
    at once read the state."""
    state = {i: (law, rings[i].place(law)) for i, law, _ in mode.ring}
    state.update({i: (None, reg) for i, reg in mode.latent})
    by_ring: dict[int, list] = {}
    for kind, det in fired:
        by_ring.setdefault(det[0], []).append((kind, det))
    centres = {}   # (u, u') per ring, formed once

    def centre(i):
        if i not in centres:
            centres[i] = rings[i].P @ q, rings[i].P @ v
        return centres[i]

    for i, items in by_ring.items():
        ring = rings[i]
        u, du = centre(i)
        if any(kind == "ring_turn" for kind, _ in items):
            raise rolling(ring, t)
        law, reg = state.get(i, (None, None))
        exits = [det[2] for kind, det in items if kind == "ring_exit"]
        moves = [det for kind, det in items if kind != "ring_exit"]
        if reg is None and moves:   # from clear, through facet k's line
            k = moves[0][2]
            along = float((ROT @ ring.normals[k]) @ u)
            reg = k if abs(along) <= ring.half_edge else ring.F + (k if along > 0 else (k - 1) % ring.F)
            law = ring.law(reg, u, du)
        elif exits:
            reg = exits[-1]
            law = None if reg is None else ring.law(reg, u, du)
        elif len(moves) == 1:
            law = moves[0][2]
        else:
            law = ring.law(reg, u, du)
        state.pop(i, None)
        if reg is not None:
            state[i] = (law, reg)
    eng, lat = [], []
    for i, (law, reg) in state.items():
        _place(eng, lat, rings[i], i, reg, law, *centre(i), t)
    return tuple(sorted(eng)), tuple(sorted(lat))


def after_impact(rings, ring_state: tuple, latent: tuple, q: np.ndarray, v: np.ndarray,
                 t: float) -> tuple[tuple, tuple]:
    """Re-read the laws after a velocity jump (an impact elsewhere): the damper's force jumps with it."""
    eng, lat = [], []
    for i, reg in [(i, rings[i].place(law)) for i, law, _ in ring_state] + list(latent):
        ring = rings[i]
        u, du = ring.P @ q, ring.P @ v
        _place(eng, lat, ring, i, reg, ring.law(reg, u, du), u, du, t)
    return tuple(sorted(eng)), tuple(sorted(lat))


def with_rings(mode: Mode, ring_state: tuple, latent: tuple) -> Mode:
    return replace(mode, ring=ring_state, latent=latent)
