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


def shifted(system, t0: float):
    """The system with its time origin at t0: f(t0 + t) as f0 + fc' cos(w t) + fs' sin(w t)."""
    if not t0 or not system.harmonic:
        return system
    c, s = np.cos(system.omega * t0), np.sin(system.omega * t0)
    return replace(system, fc=system.fc * c + system.fs * s, fs=system.fs * c - system.fc * s)


def flow(system, t0: float, q0, v0, period: float, *, jacobian: bool = True, output_dt: float | None = None,
         zeno: float = 1e-8) -> Flow:
    """Integrate ``system`` exactly from (q0, q0') at t0 over ``period`` [s]; with ``jacobian`` the monodromy
    matrix (2n x 2n) through every event. Outputs at ``output_dt`` (default period / 256), times from t0."""
    if not (np.isfinite(period) and period > 0):
        raise NsfemError(f"periodic: the period must be finite and > 0, got {period}")
    if system.schedule is not None:
        raise NsfemError("periodic: a run-up has no periodic orbit (rotation.ramp_to_hz); orbits are at constant speed")
    sysm = shifted(system, float(t0))
    integ = Exact(sysm, zeno=zeno, progress=False)
    integ.trace = [] if jacobian else None
    dt = period / 256 if output_dt is None else float(output_dt)
    with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        res = integ.run(period, dt, q0, v0)
    res.t = res.t + t0
    if not jacobian:
        return Flow(float(t0), float(period), res.q[:, -1].copy(), res.v[:, -1].copy(), None, res)
    trace = integ.trace
    Phi, approx, graze = monodromy(trace)
    last = trace[-1]
    for e in approx:
        e["t"] += t0
    for e in graze:
        e["t"] += t0
    return Flow(float(t0), float(period), last["q"].copy(), last["v"].copy(), Phi, res, approx, graze,
                trace[0]["after"])


def monodromy(trace: list) -> tuple[np.ndarray, list, list]:
    """(the product of the transition and saltation matrices along a recorded run, approximations, grazings)."""
    start = trace[0]
    n = start["q"].size
    approx, graze = [], []
    Phi, exact = impact_jacobian(start["system"], start["q"], start["v"], start["v_plus"], start["impact"])
    if not exact:
        approx.append({"t": 0.0, "why": "the start's impact outcome is not reproduced by its linear map"})
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
