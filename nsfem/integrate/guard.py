"""Guards of the event-driven loop (paper section 4): a run that cannot advance stops with a diagnosis.

The loop of :mod:`.event_driven` alternates smooth phases and events. Three ways it can fail
to reach t_end in useful time, each stopped here with a one-line :class:`~nsfem.errors.NsfemError`
naming the contacts, the kinds of events, the time and what to change (the integrator turns
it into an :class:`~nsfem.errors.IntegrationError` carrying the run up to there):

- **No time resolution** (:func:`check_phase`): a configuration whose fastest rate is not
  finite, or whose event-search step (1/8 of its fastest period or time constant,
  :meth:`Phase.max_step`) is below the resolution of time itself, 16 ulp(t_end): t + step == t,
  the search cannot advance (damping of 1e300 gives rates of 1e300 1/s).
- **Events at one time** (:class:`EventGuard`, ``same``): events in a row that advance time
  by less than 1e-12 max(1, t) s. A legitimate cascade at one instant passes each contact
  through at most its 2 + 2 r states (open, stick, slide on one of r generators or r facets)
  and, in an impact accumulation, at most n_z = ceil(ln(zeno) / ln(eps)) impacts before the
  Zeno rule makes them plastic (eps < 1; one impact for eps = 0 or 1: a plastic impact ends
  the sequence, an elastic one leaves with the approach speed, a finite flight). More events
  than the sum of these over the contacts (at least ``MAX_STUCK``) at one time is a Zeno
  point the Zeno handling did not catch, or a chatter of the transition rules.
- **No pace** (``pace``): over the last ``WINDOW`` events, time advanced by dt; at that pace
  t_end needs WINDOW (t_end - t) / dt more events. Beyond the event budget (``max_events``)
  the run cannot finish, unless an impact accumulation is under way (approach speeds
  decreasing over the window: the Zeno rule ends it after at most n_z impacts per contact).
  An unstable structure pumping energy into a see-saw of impacts (1e6 Hz: an impact every
  4e-11 s at growing speed) is stopped after ``WINDOW`` events instead of 2.5e8.
"""

from __future__ import annotations

import math
from collections import Counter, deque

import numpy as np

from ..errors import NsfemError

#: events in a row at one time always allowed (the bound below is never smaller)
MAX_STUCK = 200
#: events over which the pace is measured
WINDOW = 64
#: an accumulation lowers the largest approach speed of the window's second half below this
#: fraction of the first half's (a restitution of 0.9999 over 32 impacts lowers it 0.3 %;
#: far above the round-off of the speeds)
ACCUMULATING = 1.0 - 1e-3

_FRICTION_KINDS = {"slip", "turn", "vertex"}


def same_time_limit(contacts, zeno: float) -> int:
    """Events in a row at one time before the run is declared stuck (module docstring)."""
    total = 0
    for k in range(contacts.m):
        eps = float(contacts.eps[k])
        n_z = math.ceil(math.log(zeno) / math.log(eps)) if 0.0 < eps < 1.0 else 1
        total += n_z + 2 + 2 * int(contacts.r[k])
    return max(MAX_STUCK, total)


def same_time(t_prev: float, t: float) -> bool:
    """True when an event at t after one at t_prev did not advance time."""
    return t - t_prev <= 1e-12 * max(1.0, abs(t))


def check_phase(phase, t: float, t_end: float, mode) -> None:
    """Raise when the phase's event search cannot advance (non-finite rate or step below 16 ulp(t_end))."""
    cfg = phase.config
    rate = cfg.fastest_rate()
    step = phase.max_step(math.inf, rate)   # (the configuration's rate: as max_step finds it, once)
    resolution = 16.0 * math.ulp(max(abs(t_end), abs(t)))
    if math.isfinite(rate) and phase.finite() and (not math.isfinite(step) or step > resolution):
        return
    where = describe_mode(cfg.system.contacts, mode)
    sysm = cfg.system
    cause = likely_cause(sysm)
    if not (math.isfinite(rate) and np.all(np.isfinite(phase.A_aug))):
        raise NsfemError(f"no progress at t = {t:.6g} s: the equations of motion of configuration {where} "
                         f"overflow the floating-point range (fastest rate {rate:.3g} 1/s){cause}; "
                         "try method moreau (implicit time stepping needs no event search on these time scales)")
    raise NsfemError(f"no progress at t = {t:.6g} s: the fastest time scale of configuration {where} "
                     f"(rate {rate:.3g} 1/s) gives an event-search step of {step:.3g} s, below the time "
                     f"resolution at t_end = {t_end:g} s ({resolution:.3g} s){cause}; try method moreau (implicit "
                     "time stepping needs no event search on these time scales)")


def check_state(t: float, q: np.ndarray, v: np.ndarray, mode, system) -> None:
    """Raise when the state has left the floating-point range (an unstable structure's overflow)."""
    # (a finite sum of q' q and q' v has no non-finite entry; an overflowing one is judged entry by entry)
    if not ((math.isfinite(q @ q) and math.isfinite(v @ v)) or (np.all(np.isfinite(q)) and np.all(np.isfinite(v)))):
        raise overflow(t, mode, system)


def overflow(t: float, mode, system, what: str = "displacements or velocities") -> NsfemError:
    """The error of a motion that overflowed by t in configuration ``mode`` (``what`` did)."""
    return NsfemError(f"the motion overflowed the floating-point range at t = {t:.6g} s (non-finite {what} in "
                      f"configuration {describe_mode(system.contacts, mode)}){likely_cause(system)}")


def likely_cause(system) -> str:
    """What in M, C, Q makes time scales unresolvable: a clause naming the scene keys, or ''."""
    M, C, Q = system.M, system.C, system.Q
    with np.errstate(all="ignore"):
        m_min = float(np.min(np.abs(np.diag(M))))
        c_rate = float(np.max(np.abs(C))) / m_min if m_min > 0 else math.inf
        k_rate = math.sqrt(float(np.max(np.abs(Q))) / m_min) if m_min > 0 else math.inf
    if not math.isfinite(c_rate) or c_rate > 1e3 * max(k_rate, 1.0):
        return (f" (damping: |C| / m = {c_rate:.3g} 1/s against sqrt(|Q| / m) = {k_rate:.3g} 1/s; check "
                "damping.rayleigh, damping.external and the bearings' and elastic stators' damping)")
    return " (check the stiffness, damping and rotation.speed_hz of the scene)"


def describe_mode(contacts, mode) -> str:
    closed = [contacts.labels[k] for k in mode.closed]
    if not closed:
        return "with all contacts open"
    more = f" and {len(closed) - 4} more" if len(closed) > 4 else ""
    return "with " + ", ".join(closed[:4]) + more + " closed"


class EventGuard:
    """Watches the events of a run; :meth:`record` raises NsfemError when the run cannot advance."""

    def __init__(self, contacts, t_end: float, max_events: int, zeno: float, rings=()):
        self.contacts, self.t_end, self.max_events = contacts, float(t_end), int(max_events)
        #: the names of the events' contacts: the rigid ones, then the elastic rings (m + i)
        self.labels = tuple(contacts.labels) + tuple(rings)
        self.same_limit = same_time_limit(contacts, zeno)
        self.same = 0
        self.recent: deque = deque(maxlen=max(WINDOW, 2))
        self.count = 0

    def record(self, t_prev: float, t: float, kinds, contacts, impact: dict | None) -> None:
        """One loop iteration ending at t (an event of ``kinds`` at ``contacts``; a restart: no kinds)."""
        self.same = self.same + 1 if same_time(t_prev, t) else 0
        if not kinds:  # an rk restart of the same configuration: no event, but no progress either
            if self.same > self.same_limit:
                raise NsfemError(self._diagnosis(t, f"{self.same} restarts in a row at the same time", WINDOW))
            return
        self.count += 1
        speed = max(impact["approach_m_s"], default=0.0) if impact else None
        kinetic = impact["kinetic_after_J"] if impact else None
        self.recent.append((t, tuple(kinds), tuple(contacts), speed, kinetic))
        if self.same > self.same_limit:
            raise NsfemError(self._diagnosis(t, f"{self.same} events in a row at the same time "
                                               f"(bound {self.same_limit} from the contacts' states and "
                                               "their impact accumulations)", self.same))
        if len(self.recent) < WINDOW:
            return
        t0 = self.recent[0][0]
        dt = t - t0
        needed = (WINDOW - 1) * (self.t_end - t) / dt if dt > 0 else math.inf
        if needed <= self.max_events - self.count or self._accumulating():
            return
        raise NsfemError(self._diagnosis(
            t, f"{WINDOW} events in {dt:.3g} s (at this pace t_end = {self.t_end:g} s needs about "
               f"{needed:.2g} more events, the limit is {self.max_events:.3g})", WINDOW))

    def _accumulating(self) -> bool:
        speeds = [s for *_, s, _ in self.recent if s is not None]
        if len(speeds) < 4:
            return False
        half = len(speeds) // 2
        return max(speeds[half:]) < ACCUMULATING * max(speeds[:half])

    def _diagnosis(self, t: float, what: str, last: int) -> str:
        recent = list(self.recent)[-last:]
        cs = self.contacts
        kinds, where = Counter(), Counter()
        impacts, energies = 0, []
        for _, ks, cts, speed, kinetic in recent:
            for k in ks:
                kinds[k] += 1
            for c in cts:
                where[c] += 1
            if speed is not None:
                impacts += 1
                energies.append(kinetic)
        if not kinds:
            kinds["restart"] = len(recent)
        contacts = ", ".join(f"{self.labels[c]} ({n})" for c, n in where.most_common(4))
        if len(where) > 4:
            contacts += f" and {len(where) - 4} more"
        kind_text = ", ".join(f"{n} {k}" for k, n in kinds.most_common())
        friction = sum(n for k, n in kinds.items() if k in _FRICTION_KINDS)
        notes, advice = [], []
        if len(energies) >= 2 and energies[-1] > 1.01 * energies[0]:
            notes.append(f"the motion gains energy (kinetic {energies[0]:.3g} -> {energies[-1]:.3g} J over the "
                         "impacts): the structure is unstable here")
            advice.append("a lower rotation.speed_hz or more damping")
        if impacts >= len(recent) // 2:
            if any(c < cs.m and cs.eps[c] > 0 for c in where):
                advice.append("a lower restitution")
            advice.append("fewer contact points")
        if friction >= len(recent) // 2:
            notes.append("a stick-slip see-saw")
            advice.append("another friction coefficient or fewer friction_directions")
        if not advice:
            advice.append("fewer contact points")
        advice.append("method moreau (time stepping resolves no single events)")
        return (f"no progress at t = {t:.9g} s: {what}; events: {kind_text} ({impacts} impacts) at "
                f"{contacts or 'no contact'}" + "".join(f"; {n}" for n in notes)
                + "; try " + ", ".join(advice[:-1]) + " or " + advice[-1])
