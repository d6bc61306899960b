"""Elastic rings in the event-driven loop: their event rows and their state across events.

A ring (:mod:`nsfem.contact.ring`) is clear (its centre inside the polygon), engaged in a region
(its force law in the configuration, ``Mode.ring``) or latent in a region (beyond the polygon with
the force released, ``Mode.latent``). Its event rows, each valid while >= 0:

- ``ring_engage``: clear, per facet k the distance c - n_k . u to the facet's line; latent, -nu . N
  (the force returns);
- ``ring_release``: engaged, nu . N (the force would pull);
- ``ring_exit``: engaged or latent, the region's boundaries (to a neighbouring region, or inside);
- ``ring_turn``: engaged with friction, s times the slip velocity (it stops: the shaft would roll on
  the ring, which the event-driven methods do not hold).

A row's contact is m + i (m rigid contacts, ring i), so that rows, events and the guard name rings.
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
    engaged = {i: (reg, s) for i, reg, s in mode.ring}
    latent = dict(mode.latent)
    for i, ring in enumerate(rings):
        U, dU = ring.P @ Pq, ring.P @ Pv
        if i in engaged:
            reg, s = engaged[i]
            N = ring.force_rows(reg, Pq, Pv, const)
            nu = ring.parts(reg)[2]
            add(nu @ N, "ring_release", m + i, (i, reg))
            _exits(ring, reg, U, const, add, m + i, i)
            if ring.friction and s:
                rate = (ROT @ nu) @ dU + ring.frame_spin * (nu @ U)
                rate[const] += ring.surface_speed
                add(s * rate, "ring_turn", m + i, (i, reg))
        elif i in latent:
            reg = latent[i]
            N = ring.force_rows(reg, Pq, Pv, const)
            add(-(ring.parts(reg)[2] @ N), "ring_engage", m + i, (i, reg, None))
            _exits(ring, reg, U, const, add, m + i, i)
        else:
            for k, n in enumerate(ring.normals):
                row = -(n @ U)
                row[const] += ring.clearance
                add(row, "ring_engage", m + i, (i, None, k))


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
    """(ring, latent) of ``Mode`` from a state: engaged where beyond the polygon with nu . N > 0."""
    eng, lat = [], []
    for i, ring in enumerate(rings):
        u, du = ring.P @ q, ring.P @ v
        reg = ring.region(u)
        if reg is None:
            continue
        if float(ring.normal_force(reg, u, du)) > 0.0:
            eng.append((i, reg, _sign(ring, reg, u, du, t)))
        else:
            lat.append((i, reg))
    return tuple(eng), tuple(lat)


def after_event(rings, mode: Mode, fired: list, q: np.ndarray, v: np.ndarray, t: float) -> tuple[tuple, tuple]:
    """(ring, latent) after the ring rows ``fired`` ((kind, detail) pairs) at t, from ``mode``'s. A lone exit
    reads engagement in the new region (nu . N changes with nu there)."""
    engaged = {i: reg for i, reg, _ in mode.ring}
    latent = dict(mode.latent)
    state = {i: ("engaged", reg) for i, reg in engaged.items()}
    state.update({i: ("latent", reg) for i, reg in latent.items()})
    by_ring: dict[int, list] = {}
    for kind, det in fired:
        by_ring.setdefault(det[0], []).append((kind, det))
    for i, items in by_ring.items():
        ring = rings[i]
        u = ring.P @ q
        kinds = {k for k, _ in items}
        if "ring_turn" in kinds:
            raise rolling(ring, t)
        flag, reg = state.get(i, ("clear", None))
        for kind, det in items:   # the region first
            if kind == "ring_exit":
                flag, reg = (flag, det[2]) if det[2] is not None else ("clear", None)
        if flag != "clear" and kinds == {"ring_exit"}:   # nu changes with the region: read nu . N there
            flag = "engaged" if float(ring.normal_force(reg, u, ring.P @ v)) > 0.0 else "latent"
        for kind, det in items:
            if kind == "ring_engage" and det[1] is None:     # from clear, through facet k's line
                k = det[2]
                along = float((ROT @ ring.normals[k]) @ u)
                reg = k if abs(along) <= ring.half_edge else ring.F + (k if along > 0 else (k - 1) % ring.F)
                flag = "engaged"
            elif kind == "ring_engage":
                flag = "engaged"
            elif kind == "ring_release":
                flag = "latent" if ring.damping > 0.0 else "clear"
        if flag == "clear" or reg is None:
            state.pop(i, None)
        else:
            state[i] = (flag, reg)
    eng = tuple(sorted((i, reg, _sign(rings[i], reg, rings[i].P @ q, rings[i].P @ v, t))
                       for i, (flag, reg) in state.items() if flag == "engaged"))
    lat = tuple(sorted((i, reg) for i, (flag, reg) in state.items() if flag == "latent"))
    return eng, lat


def after_impact(rings, ring_state: tuple, latent: tuple, q: np.ndarray, v: np.ndarray, t: float) -> tuple[tuple, tuple]:
    """Re-read engagement after a velocity jump (an impact elsewhere): the damper's force jumps with it."""
    eng, lat = [], []
    for i, reg, _ in ring_state:
        ring = rings[i]
        u, du = ring.P @ q, ring.P @ v
        (eng if float(ring.normal_force(reg, u, du)) > 0.0 else lat).append((i, reg))
    for i, reg in latent:
        ring = rings[i]
        u, du = ring.P @ q, ring.P @ v
        (eng if float(ring.normal_force(reg, u, du)) > 0.0 else lat).append((i, reg))
    return (tuple(sorted((i, reg, _sign(rings[i], reg, rings[i].P @ q, rings[i].P @ v, t)) for i, reg in eng)),
            tuple(sorted(lat)))


def with_rings(mode: Mode, ring_state: tuple, latent: tuple) -> Mode:
    return replace(mode, ring=ring_state, latent=latent)
