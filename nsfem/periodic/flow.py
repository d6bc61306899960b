"""The exact flow over one period and its monodromy matrix.

The event-driven integrator (:class:`~nsfem.integrate.event_driven.Exact`) records its phases and
events (``trace``); the monodromy matrix d x(t0 + T) / d x(t0), x = (q, q'), is the product of
each phase's transition matrix (:func:`.variational.phase_transition`) and each event's saltation
matrix (:mod:`.saltation`), in the order met: no finite differences of the flow.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import NsfemError
from ..integrate.base import single_threaded_blas
from ..integrate.event_driven import Exact
from ..result import Result
from .arguments import real_number, vector
from .saltation import impact_jacobian, row_coefficients, row_gradient, saltation
from .variational import phase_transition, state_rate


@dataclass
class Flow:
    """The exact flow from (t0, q0, q0') over ``period``: the end state, its monodromy matrix and the run."""

    t0: float
    period: float
    q: np.ndarray
    v: np.ndarray
    monodromy: np.ndarray | None
    result: Result
    #: events whose saltation matrix was not formed exactly: [{"t", "why"}] (grazing, simultaneous rows, an impact
    #: outcome the linear map does not reproduce, a round ring's turn)
    approximations: list = field(default_factory=list)
    #: grazing events met: [{"t", "contacts"}]
    grazing: list = field(default_factory=list)
    #: the configuration (:class:`~nsfem.integrate.configuration.Mode`) the flow started in (after the start's
    #: resolution), None without a recorded run
    start_mode: object = None
    #: the recorded run (:attr:`~nsfem.integrate.event_driven.EventDriven.trace`), None without the Jacobian
    trace: list | None = field(default=None, repr=False)


def shifted(system, t0: float):
    """The system with its time origin at t0: f(t0 + t) as f0 + fc' cos(w t) + fs' sin(w t)."""
    if not t0 or not system.harmonic:
        return system
    c, s = np.cos(system.omega * t0), np.sin(system.omega * t0)
    return replace(system, fc=system.fc * c + system.fs * s, fs=system.fs * c - system.fc * s)


class FlowMap:
    """x0 -> the exact flow over ``period`` from t0 (a :class:`Flow`), for many starts of one system: the shooting
    method's map. The configurations met (their eigen-decompositions) are kept from one start to the next, and may
    be shared with another run's (:meth:`share`). No energy balance is booked (``Result.energy`` is empty)."""

    def __init__(self, system, t0: float, period: float, *, output_dt: float | None = None, zeno: float = 1e-8):
        period, t0 = real_number("the period", period, positive=True), real_number("t0", t0)
        if output_dt is not None:
            output_dt = real_number("output_dt", output_dt, positive=True)
            if output_dt > period:
                raise NsfemError(f"periodic: output_dt must lie in (0, the period {period:g} s], got {output_dt:g}")
        zeno = real_number("zeno", zeno, positive=True)
        if system.schedule is not None:
            raise NsfemError("periodic: a run-up has no periodic orbit (rotation.ramp_to_hz); orbits are at constant "
                             "speed")
        round_ = system.info.get("round_rings") or ()
        if round_:
            raise NsfemError(f"periodic: stator {round_[0]} has shape = \"round\": its turning facet keeps a state of "
                             "its own (turn angle, wedge, distance) besides (q, q'), so its flow over a period is not a "
                             "map of the state alone; set shape = \"polygon\" for orbits (256 facets keep the radius "
                             "within 7.5e-5 of the clearance)")
        self.system, self.t0, self.period = system, float(t0), float(period)
        self.output_dt = period / 256 if output_dt is None else float(output_dt)
        # the system itself, run from t0 (Exact.run's t_start): its configurations are those of every section
        self._integrator = Exact(system, zeno=zeno, progress=False, energy_balance=False)
        self._integrator.keep_configurations = True

    def share(self, other) -> bool:
        """Use and add to the configurations ``other`` keeps (a :class:`FlowMap`, an
        :class:`~nsfem.integrate.event_driven.EventDriven` run with ``keep_configurations`` or the store of one,
        :meth:`~nsfem.integrate.event_driven.EventDriven.kept`: a lead transient's) where they are this map's: of the
        same system (the same object; any section t0: the flows start at t0 on the forcing's clock). The flows are
        the same, bit for bit: a configuration depends on the system and its mode alone. Returns whether they are
        shared."""
        store = other._integrator.kept() if isinstance(other, FlowMap) else \
            other if isinstance(other, dict) else other.kept()
        mine = self._integrator
        if not store or store.get("system") is not mine.system or store.get("modes") is mine._cache:
            return False
        mine._cache, mine._systems, mine._gaps = store["modes"], store["systems"], store["gaps"]
        return True

    def __call__(self, q0, v0, jacobian: bool = True) -> Flow:
        n = self.system.n
        q0, v0 = (None if x is None else vector(x, n) for x in (q0, v0))
        integ = self._integrator
        integ.trace = [] if jacobian else None
        with single_threaded_blas():
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # (every time on the forcing's clock)
                res = integ.run(self.t0 + self.period, self.output_dt, q0, v0, t_start=self.t0)
            if not jacobian:
                return Flow(self.t0, self.period, res.q[:, -1].copy(), res.v[:, -1].copy(), None, res)
            trace, integ.trace = integ.trace, None
            Phi, approx, graze = monodromy(trace)
        last = trace[-1]
        return Flow(self.t0, self.period, last["q"].copy(), last["v"].copy(), Phi, res, approx, graze,
                    trace[0]["after"], trace)


def flow(system, t0: float, q0, v0, period: float, *, jacobian: bool = True, output_dt: float | None = None,
         zeno: float = 1e-8) -> Flow:
    """Integrate ``system`` exactly from (q0, q0') at t0 over ``period`` [s]; with ``jacobian`` the monodromy
    matrix (2n x 2n) through every event. Outputs at ``output_dt`` (default period / 256), times from t0."""
    return FlowMap(system, t0, period, output_dt=output_dt, zeno=zeno)(q0, v0, jacobian)


#: a velocity change at the start below this fraction of the velocity is no impact: contacts closed at the section
#: approach at round-off (a state on its constraints to ~1e-16; the crack's orbit at a section inside its closed
#: stretch: 1.3e-27 m/s against 0.045 m/s) and the integrator's start settles them; a perturbation meets no impact
#: there, the map is not one-sided
START_SETTLING = 1e-12


def monodromy(trace: list) -> tuple[np.ndarray, list, list]:
    """(the product of the transition and saltation matrices along a recorded run, approximations, grazings)."""
    start = trace[0]
    approx, graze = [], []
    Phi, exact = impact_jacobian(start["system"], start["q"], start["v"], start["v_plus"], start["impact"])
    if not exact:
        approx.append({"t": start["t"], "why": "the start's impact outcome is not reproduced by its linear map"})
    elif start["impact"] is not None and np.abs(start["v_plus"] - start["v"]).max() > \
            START_SETTLING * np.abs(start["v"]).max():
        # an impact at the start itself: a perturbation off the stop meets it later (a time shift the start has no
        # event row for) and one into it penetrates: the map is one-sided there, its matrix the impact's alone
        approx.append({"t": start["t"], "why": "an impact at the start (the map is one-sided there)"})
    steps = trace[1:]
    for j, step in enumerate(steps):
        phase = step["phase"]
        Phi = phase_transition(phase.config, step["t1"] - step["t0"]) @ Phi
        ev = step.get("event")
        if ev is None:
            continue
        after = steps[j + 1]["phase"] if j + 1 < len(steps) else None
        Dg, exact = impact_jacobian(step["system"], step["q"], step["v"], step["v_plus"], step["impact"])
        t = step["t1"]
        if not exact:
            approx.append({"t": t, "why": "an impact outcome its linear map does not reproduce"})
        rows = [i for j_, i in enumerate(ev.rows) if not ev.graze[j_]]
        if len(rows) < len(ev.rows):
            graze.append({"t": t, "contacts": sorted({int(step["rows"].contacts[i]) for i, g in zip(ev.rows, ev.graze)
                                                      if g})})
        if not rows:
            Phi = Dg @ Phi
            continue
        i = rows[0]
        rows_ = step["rows"]
        # row i of the phase's rows is row i of the configuration's only where the phase searched the
        # configuration's own rows: a closed round ring swaps its other facets' gap rows for its wedge rows
        own = rows_.H.shape[0] == row_coefficients(phase.config, step["mode"]).shape[0]
        grad = row_gradient(phase.config, step["mode"], i) if own else None
        rate = 0.0
        if grad is not None:   # (Hd is not cached for every phase's rows: formed as the event search does)
            rate = float((rows_.Hd[i] if rows_.Hd is not None else rows_.H[i] @ phase.A_aug) @ phase.xi(float(t)))
        if grad is None or after is None or rate == 0.0:
            Phi = Dg @ Phi
            if grad is None:
                approx.append({"t": t, "why": "a round ring's turn (the facet follows the contact point)"})
            elif after is not None:
                approx.append({"t": t, "why": "an event row with zero rate"})
            continue
        if len(rows) > 1:
            approx.append({"t": t, "why": f"{len(rows)} event rows at once (the first one's time shift used)"})
        f_minus = state_rate(phase, t)
        f_plus = state_rate(after, t)
        Phi = saltation(Dg, f_minus, f_plus, grad, rate) @ Phi
    return Phi, approx, graze


def quiet_phase(times, period: float) -> float:
    """The phase in [0, ``period``) in the middle of the longest stretch of one period without events, the events at
    ``times`` [s] (any times: taken modulo the period); 0.0 without events. A Poincare section there lies as far
    from the period's events as it can: the shooting's map is smooth there, and on the shipped crack scene far
    better conditioned (docs/performance.md)."""
    period = real_number("the period", period, positive=True)
    try:
        phases = sorted({float(t) % period for t in times})
    except (TypeError, ValueError):
        raise NsfemError(f"periodic: event times must be numbers, got {str(times)[:40]!r}") from None
    if not phases:
        return 0.0
    if not all(np.isfinite(phases)):
        raise NsfemError("periodic: an event time is not finite")
    length, after = max((b - a, a) for a, b in zip(phases, phases[1:] + [phases[0] + period]))
    return (after + 0.5 * length) % period


#: a gap whose smallest value over an open phase is below this fraction of its range over the period is near grazing
NEAR_GRAZING = 1e-3
#: samples per phase at most when looking for a gap's minima (each refined on the closed form)
_GRAZE_SAMPLES = 512


def near_grazing(fl: Flow, rel: float = NEAR_GRAZING) -> list[dict]:
    """Gaps that come within ``rel`` of their range over the period to zero without closing: per contact and open
    phase, the local minima of g(t) on a grid of the phase's sampling step (:meth:`Phase.max_step`), each refined
    on the exact motion (bounded Brent to 1e-12 of the phase's length); [{"contact", "t", "gap_min"}], t on the
    forcing's clock (as the flow's). A gap that closes at an event is not grazing; a tangential touch the event
    search fired on is in ``fl.grazing``."""
    from scipy.optimize import minimize_scalar

    if fl.trace is None:
        raise ValueError("near_grazing needs a flow recorded with its Jacobian")
    res = fl.result
    m = res.gap.shape[0]
    if not m or not res.t.size:
        return []
    span = np.ptp(res.gap, axis=1) if res.t.size > 1 else np.zeros(m)
    out = []
    for step in fl.trace[1:]:
        phase, mode = step["phase"], step["mode"]
        cs = phase.config.system.contacts
        open_ = [k for k in range(min(cs.m, m)) if k not in mode.closed]
        if not open_:
            continue
        t0, t1 = step["t0"], step["t1"]
        if t1 <= t0:
            continue
        nsamp = int(min(_GRAZE_SAMPLES, max(16, np.ceil((t1 - t0) / phase.max_step(t1 - t0)))))
        ts = np.linspace(t0, t1, nsamp + 1)
        Pq = phase.q_map()
        # the open gaps' rows of xi (their products with the mode shapes formed once: row_map), not all of xi
        G = phase.row_map(cs.JN[:, open_].T @ Pq)(ts) + cs.jN[open_][:, None]
        # the samples that are local minima within rel of each gap's scale (whole arrays: 64 facets x 512 samples)
        scales = np.maximum(span[open_], np.abs(G).max(axis=1))
        inner = G[:, 1:-1]
        low = (inner <= G[:, :-2]) & (inner <= G[:, 2:]) & (inner <= (rel * scales + 1e-300)[:, None])
        for j, i in zip(*np.nonzero(low)):
            k, i = open_[j], int(i) + 1
            gap = lambda t, k=k: float(cs.JN[:, k] @ (Pq @ phase.xi(float(t))) + cs.jN[k])  # noqa: E731
            r = minimize_scalar(gap, bounds=(ts[i - 1], ts[i + 1]), method="bounded",
                                options={"xatol": 1e-12 * (t1 - t0)})
            if r.fun > 0.0:
                out.append({"contact": int(k), "t": float(r.x), "gap_min": float(r.fun)})
    return out
