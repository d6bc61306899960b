"""The contact counts and maxima of a run, defined once, per contact point and per part.

A part is what a rotor engineer names: a delamination (its contact points along one interface), a stator
ring (its facets), a crack (its front's points) or a stop (one obstacle). :meth:`nsfem.result.Result.summary`
(the run JSON), the run's text summary, gap.png and forces.png all read their numbers from :func:`tally`:

- an **impact** is an impact record of the integrator (a velocity jump resolved by an impulse) in which
  some contact point takes a positive normal impulse. A point's impacts are those in which it does, a
  part's those in which any of its points does: two points struck in one impact make one impact of
  their part and of the run;
- a point's **normal force** is its lambda_N [N] at the output times. A part's is the resultant of its
  points' forces: their sum for a delamination, a crack and a stop (parallel normals) and, for a ring,
  the vector sum over its facets, sum_k lambda_k n_k with n_k = (cos, sin)(theta_k) in the y-z plane
  of the run's frame (its magnitude, and its angle from +y towards +z). The **tangential force** is
  resolved the same way (a ring's circumferential friction along t_k = (-sin, cos)(theta_k));
- a part's **impulse** in an impact is the resultant of its points' impulses [N s], resolved as its force.
  Impulses are tallied apart from forces: an impact-only run has impulses and no force;
- a part's **gap** at a time is the smallest of its points' gaps (a ring: its clearance to the shaft,
  a crack: the more open of its front's ends is its opening, drawn by gap.png; the tally keeps the
  smallest), its **closed fraction** the share of the run's time with at least one of its points
  closed: exact between events when the integrator records them, else the share of output times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

#: the kinds of part, in the words of the run JSON
KINDS = ("delamination", "ring", "crack", "stop")


@dataclass(frozen=True)
class Part:
    """A contact part: ``name`` (the scene key: ``delamination.0``, ``stator.1``, ``crack.0``, ``obstacle.2``),
    ``kind`` (one of :data:`KINDS`), ``rows`` (its contact rows in the result's arrays) and, for a ring,
    ``angles`` (its facets' normal angles [rad], one per row)."""

    name: str
    kind: str
    rows: tuple[int, ...]
    angles: tuple[float, ...] = ()

    def record(self) -> dict:
        return {"name": self.name, "kind": self.kind, "rows": list(self.rows), "angles": list(self.angles)}

    @classmethod
    def from_record(cls, d: dict) -> Part:
        return cls(str(d["name"]), str(d["kind"]), tuple(int(r) for r in d["rows"]),
                   tuple(float(a) for a in d.get("angles", ())))


def parts_of_contacts(contacts: Sequence) -> list[Part]:
    """The parts of a stack's contacts (:class:`nsfem.stack.Contact`, in row order): interface points
    grouped by the pair of layers they join, a stator's facets by ring, a crack's front points by crack,
    each other obstacle a stop of its own."""
    groups: dict = {}
    for k, c in enumerate(contacts):
        label = c.label or f"contact.{k}"
        if c.kind == "interface":
            name = label.rsplit(".", 1)[0] if label.startswith("delamination.") \
                else f"interface {c.segments[0]}/{c.segments[1]}"
            key, kind = ("delamination", tuple(c.segments)), "delamination"
        elif c.angle is not None:
            name = label.rsplit(".", 1)[0]
            key, kind = ("ring", name), "ring"
        elif c.kind == "crack":
            name = c.table_key
            key, kind = ("crack", name), "crack"
        else:
            name, key, kind = label, ("stop", k), "stop"
        g = groups.setdefault(key, {"name": name, "kind": kind, "rows": [], "angles": []})
        g["rows"].append(k)
        if kind == "ring":
            g["angles"].append(float(c.angle))
    return [Part(g["name"], g["kind"], tuple(g["rows"]), tuple(g["angles"])) for g in groups.values()]


def parts_of_labels(labels: Sequence[str]) -> list[Part]:
    """The parts read from contact labels alone (a results file without its model): ``delamination.<i>.<k>``,
    ``stator.<i>.<k>`` (facet k of F at 2 pi k / F, as the scene builds them), ``crack.<i>.<k>``; any other
    label is a stop.

    >>> for p in parts_of_labels(["delamination.0.0", "delamination.0.1", "stator.0.0", "stator.0.1", "obstacle.0"]):
    ...     print(p.name, p.kind, p.rows, [round(a, 4) for a in p.angles])
    delamination.0 delamination (0, 1) []
    stator.0 ring (2, 3) [0.0, 3.1416]
    obstacle.0 stop (4,) []
    """
    labels = [str(s) for s in labels]
    groups: dict = {}
    for k, lab in enumerate(labels):
        head, _, tail = lab.rpartition(".")
        root = head.split(".", 1)[0]
        kind = {"delamination": "delamination", "stator": "ring", "crack": "crack"}.get(root)
        if kind is None or head.count(".") != 1 or not tail.isdigit():
            kind, head = "stop", lab
        groups.setdefault(head, {"kind": kind, "rows": [], "facet": []})
        groups[head]["rows"].append(k)
        groups[head]["facet"].append(int(tail) if kind == "ring" else 0)
    out = []
    for name, g in groups.items():
        angles = ()
        if g["kind"] == "ring":
            F = max(g["facet"]) + 1
            angles = tuple(2.0 * math.pi * i / F for i in g["facet"])
        out.append(Part(name, g["kind"], tuple(g["rows"]), angles))
    return out


def system_parts(system) -> list[Part]:
    """The parts of a :class:`~nsfem.integrate.ContactSystem`'s contacts (its model's stack when it carries
    one, else the labels)."""
    cs = system.model_contacts
    model = (getattr(system, "info", None) or {}).get("model")
    if model is not None and len(model.stack.contacts) == cs.m:
        return parts_of_contacts(model.stack.contacts)
    return parts_of_labels(cs.labels)


def result_parts(result) -> list[Part]:
    """The parts recorded in ``result.info['parts']`` (:func:`nsfem.simulate.run_scene`) when they hold each
    contact row once, else those of its contact labels (``info['contacts']``), else one stop per contact row."""
    m = result.gap.shape[0]
    rec = result.info.get("parts")
    if rec:
        try:
            parts = [Part.from_record(d) for d in rec]
        except (KeyError, TypeError, ValueError):   # a results file edited by hand: read the labels instead
            parts = []
        rows = sorted(k for p in parts for k in p.rows)
        if rows == list(range(m)) and all(p.kind in KINDS for p in parts):
            return parts
    labels = result.info.get("contacts")
    if labels is None or len(labels) != m:
        labels = [f"contact.{k}" for k in range(m)]
    return parts_of_labels(labels)


# --------------------------------------------------------------------------- arrays in, arrays out
def impulse_table(impacts: Sequence[dict], m: int,
                  index: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(t (I,), P (m, I)): each impact record's time and the normal impulse [N s] of each contact row in it
    (0 for the rows it does not hold; a negative (round-off) or non-finite impulse counts as none).
    ``index`` maps the record's contact numbers to result rows (the rigid contacts' places among a model's
    contacts with elastic rings); a number outside is ignored."""
    t = np.array([float(im.get("t", np.nan)) for im in impacts], dtype=float)
    P = np.zeros((m, len(impacts)))
    for j, im in enumerate(impacts):
        for c, p in zip(im.get("contacts", []), im.get("impulse_Ns", [])):
            k = int(c) if index is None else (int(index[int(c)]) if 0 <= int(c) < len(index) else -1)
            if 0 <= k < m and math.isfinite(float(p)) and float(p) > 0.0:   # a negative one is round-off
                P[k, j] += float(p)
    return t, P


def resultant(part: Part, normal: np.ndarray, tangential: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(|N|, |T|, angle) of a part's resultant normal and tangential force (or impulse) over the columns of
    ``normal`` (m, K) and ``tangential`` (m, 2, K): the sums of its rows; for a ring the vector sums over its
    facets (N = sum lambda_k n_k, T = sum (lambda_T,k0 t_k + lambda_T,k1 e_x)) and the angle of N [rad]
    from +y towards +z (NaN where N = 0); ``angle`` is None for the other kinds."""
    rows = list(part.rows)
    lam = np.asarray(normal, dtype=float)[rows]
    K = lam.shape[1] if lam.ndim == 2 else 0
    tan = np.zeros((len(rows), 2, K)) if tangential is None else np.asarray(tangential, dtype=float)[rows]
    if part.kind == "ring" and len(part.angles) == len(rows):
        a = np.asarray(part.angles, dtype=float)
        n = np.stack([np.cos(a), np.sin(a)])                 # 2 x F
        t = np.stack([-np.sin(a), np.cos(a)])
        N = n @ lam                                           # 2 x K
        T = t @ tan[:, 0, :]
        axial = tan[:, 1, :].sum(axis=0)
        mag = np.hypot(N[0], N[1])
        angle = np.where(mag > 0, np.arctan2(N[1], N[0]), np.nan)
        return mag, np.sqrt(T[0] ** 2 + T[1] ** 2 + axial ** 2), angle
    T = tan.sum(axis=0)                                       # parallel normals: the tangents add too
    return lam.sum(axis=0), np.hypot(T[0], T[1]), None


def closed_spans(t: np.ndarray, state: np.ndarray, events: Sequence[dict], rows, every: bool = False,
                 index: Sequence[int] | None = None) -> list[tuple[float, float]]:
    """[(t_close, t_release)] of the contact rows ``rows``: closed while any of them is (all of them with
    ``every``). From the events when the integrator records them (exact to round-off; ``index`` maps
    their contact numbers to result rows), else from the sampled ``state`` (m, K), a span then running
    from its first closed sample to its last."""
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return []
    rows = [int(r) for r in np.atleast_1d(rows)]
    together = all if every else any
    events = [e for e in events if isinstance(e.get("after"), dict) and "closed" in e["after"]]
    inverse = None if index is None else {int(r): j for j, r in enumerate(index)}
    if events and (inverse is None or all(r in inverse for r in rows)):
        ids = rows if inverse is None else [inverse[r] for r in rows]
        spans = []
        closed, start = together(state[r, 0] != 0 for r in rows), float(t[0])
        for e in sorted(events, key=lambda e: e["t"]):
            shut = set(e["after"]["closed"])
            now = together(i in shut for i in ids)
            if now and not closed:
                start = float(e["t"])
            elif closed and not now:
                spans.append((start, float(e["t"])))
            closed = now
        if closed:
            spans.append((start, float(t[-1])))
        return spans
    on = (np.all if every else np.any)(np.asarray(state)[rows] != 0, axis=0)
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    return [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2])]


# --------------------------------------------------------------------------- the tally
@dataclass
class PartTally:
    """One part's numbers (see the module's definitions) and the series gap.png and forces.png draw."""

    part: Part
    impacts: int
    max_normal_force_N: float
    max_point_force_N: float
    max_tangential_force_N: float
    max_impulse_Ns: float
    min_gap_m: float | None
    closed_fraction: float
    gap: np.ndarray = field(repr=False)             # (K,) the smallest gap of its points
    force: np.ndarray = field(repr=False)           # (K,) |N| of the resultant
    friction: np.ndarray = field(repr=False)        # (K,) |T| of the resultant
    angle: np.ndarray | None = field(repr=False)    # (K,) a ring's force angle [rad], NaN while unloaded
    impact_t: np.ndarray = field(repr=False)        # (I_part,) its impacts' times
    impact_Ns: np.ndarray = field(repr=False)       # (I_part,) its resultant impulse in each
    spans: list = field(repr=False)                 # its closed intervals
    angle_at_max_deg: float | None = None

    def record(self) -> dict:
        """The run JSON's entry of the part."""
        out = {"name": self.part.name, "kind": self.part.kind, "contacts": len(self.part.rows),
               "impacts": self.impacts, "max_normal_force_N": self.max_normal_force_N,
               "max_point_force_N": self.max_point_force_N, "max_tangential_force_N": self.max_tangential_force_N,
               "max_impulse_Ns": self.max_impulse_Ns, "min_gap_m": self.min_gap_m,
               "closed_fraction": self.closed_fraction}
        if self.part.kind == "ring":
            out["force_angle_deg"] = self.angle_at_max_deg
        return out


@dataclass
class Tally:
    """The run's counts: ``impacts`` (records with a positive impulse), ``max_impulse_Ns`` and
    ``max_normal_force_N`` (the largest at one contact point), per part a :class:`PartTally`, and
    ``shared_impacts``, the impacts that strike more than one part (counted once for the run, once for each
    of its parts)."""

    impacts: int
    max_impulse_Ns: float
    max_normal_force_N: float
    parts: list[PartTally]
    shared_impacts: int = 0

    def part(self, name: str) -> PartTally:
        return next(p for p in self.parts if p.part.name == name)


def tally(result, parts: Sequence[Part] | None = None) -> Tally:
    """The counts and maxima of a :class:`~nsfem.result.Result` (module docstring), per part of ``parts``
    (default :func:`result_parts`)."""
    m = result.gap.shape[0]
    t = np.asarray(result.t, dtype=float)
    K = t.size
    parts = result_parts(result) if parts is None else list(parts)
    index = result.info.get("contact_index")
    it, P = impulse_table(result.impacts, m, index)
    hit = P > 0.0
    # the event-driven methods book the closed time between events (info['closed_fraction']); the others sample
    timed = "closed_fraction" in result.info and any(isinstance(e.get("after"), dict) for e in result.events)
    rigid = None if index is None else set(int(r) for r in index)
    span = float(t[-1] - t[0]) if K > 1 else 0.0
    out = []
    parts_struck = np.zeros(it.size, int)
    for p in parts:
        rows = list(p.rows)
        struck = hit[rows].any(axis=0) if rows else np.zeros(it.size, bool)
        parts_struck += struck
        imp, _, _ = resultant(p, P[:, struck])
        force, friction, angle = resultant(p, result.normal_force, result.tangential_force)
        gap = result.gap[rows].min(axis=0) if rows and K else np.zeros(K)
        exact = timed and span > 0 and (rigid is None or set(rows) <= rigid)
        spans = closed_spans(t, result.state, result.events if exact else [], rows, index=index) if rows else []
        if exact:
            closed = sum(b - a for a, b in spans) / span
        else:
            closed = float(np.any(result.state[rows] != 0, axis=0).mean()) if rows and K else 0.0
        top = int(np.argmax(force)) if K else 0
        deg = None
        if angle is not None and K and force[top] > 0:
            deg = float(np.degrees(angle[top]))
        out.append(PartTally(
            p, int(struck.sum()), float(force.max(initial=0.0)) if K else 0.0,
            float(result.normal_force[rows].max(initial=0.0)) if rows and K else 0.0,
            float(friction.max(initial=0.0)) if K else 0.0, float(imp.max(initial=0.0)),
            float(gap.min()) if rows and K else None, float(min(max(closed, 0.0), 1.0)), gap, force, friction,
            angle, it[struck], imp, spans, deg))
    return Tally(int(hit.any(axis=0).sum()), float(P.max(initial=0.0)),
                 float(result.normal_force.max(initial=0.0)) if m and K else 0.0, out, int((parts_struck > 1).sum()))
