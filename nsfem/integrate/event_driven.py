"""Event-driven integration (paper section 4): ``exact`` and ``rk``.

Both methods run the same loop: in the current contact configuration propagate to the
next event (:mod:`.events`), resolve it (:func:`.transitions.resolve`: impact LCP, then
transition LCP), and continue in the new configuration. They differ only in how the smooth
phase is propagated:

- ``exact``: in closed form (:class:`.configuration.Phase`), events located on the exact
  solution with a sampling step bounded by the fastest time scale and bracketed Newton refinement;
- ``rk``: scipy's ``solve_ivp`` (DOP853 by default, RK45 selectable) on the configuration's
  ODE with terminal event functions, the paper's own approach, kept for comparison (a
  grazing dip between two steps can be missed there, as in the paper).

Energy (reported as ``energy['relative_residual']``): E = 1/2 q'^T M q' + 1/2 q^T K q with K
the symmetric part of Q (elastic and centrifugal potential). Its balance
E(t) - E(0) = W_external - W_dissipated, with W_external = int f(t) . q' dt (constant and
harmonic loads), W_dissipated = int (q'^T D q' + q'^T P q' ... ) the damping (symmetric part
of C), circulatory (skew part of Q) and friction work plus the kinetic energy lost in
impacts, is integrated by 4-point Gauss-Legendre quadrature on the sampling grid; the
residual |E(T) - E(0) - W_ext + W_diss| / max E measures the integration error.
"""

from __future__ import annotations

import copy
import math
import time
from bisect import bisect_left, bisect_right

import numpy as np

from ..errors import IntegrationError, NsfemError
from ..linalg import factorize
from ..contact.ring import ROT, generalized_force, potential, unheld
from ..result import Result
from . import core
from .base import Integrator, Progress, close_energy, initial_state, output_times
from .closed_form import group_integrals
from .configuration import Configuration, Mode, Phase, matrix_key
from .events import Event, Rows, event_rows, first_event, round_off
from .guard import EventGuard, check_phase, check_state, overflow
from .rings import after_event, after_impact, initial_rings, with_rings
from .round import DELTA, conform, polygon_outputs, relax, round_rings, turn, turned, wedge_rows
from .transitions import Memory, hold_degenerate, resolve

#: Gauss-Legendre nodes and weights on [0, 1]
_GX, _GW = np.polynomial.legendre.leggauss(4)
_GX, _GW = 0.5 * (_GX + 1.0), 0.5 * _GW


def _gauss_nodes(theta: float) -> int:
    """Gauss-Legendre nodes that integrate e^{i theta s} over s in [0, 1] to 1e-17 relative: the
    smallest n with theta^(2n) (n!)^4 / ((2n + 1) ((2n)!)^3) <= 1e-17 (the remainder term with
    |f^(2n)| <= theta^(2n)); at least 4."""
    theta = max(theta, 1e-3)
    for n in range(4, 64):
        if 2 * n * math.log(theta) + 4 * math.lgamma(n + 1) - math.log(2 * n + 1) - 3 * math.lgamma(2 * n + 1) \
                <= math.log(1e-17):
            return n
    return 64


def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


class EventDriven(Integrator):
    """The event-driven loop; subclasses implement :meth:`_advance`."""

    name = "event-driven"
    #: rigid stator rings as a facet that turns with the contact point (:mod:`.round`); else the fixed polygon
    round_rings = False
    #: configurations kept with round rings (their turns make new ones, met once or twice): the recent half
    max_configurations = 512

    def __init__(self, system, zeno: float = 1e-8, max_events: int = 10_000_000, progress: bool | None = None,
                 energy_balance: bool = True, configurations: dict | None = None, **options):
        super().__init__(system, **options)
        if not (0 < zeno < 1):
            raise NsfemError(f"zeno must lie in (0, 1), got {zeno}")
        self.zeno, self.max_events, self.progress = zeno, int(max_events), progress
        self._cache: dict = {}
        #: the gaps' constants g0 of the modes without sticking or edge rows (:meth:`_phase`), by mode
        self._gaps: dict = {}
        #: configurations with elastic rings by what sets their matrices (:meth:`_build`)
        self._systems: dict = {}
        #: the round rings (:mod:`.round`) and the system of the fixed polygon they turn
        self._rings, self._polygon = (), system
        #: a list to record the run in (None: not recorded): one dict per phase (``phase``, ``rows``, ``mode``,
        #: ``t0``, ``t1``, the state at its end ``q``, ``v``; at an event also ``event``, the velocity after it
        #: ``v_plus``, the mode after it ``after``, the impact record ``impact`` and the ``system`` it was resolved
        #: in), after one dict for the start (``start``: ``q``, ``v`` given, ``v_plus``, ``impact``). What the
        #: periodic orbits' monodromy matrix is formed from (:mod:`nsfem.periodic`)
        self.trace: list | None = None
        #: keep the configurations (their decompositions) from one run to the next of the same system (the runs of
        #: a shooting method); never with round rings (their turns make the configurations)
        self.keep_configurations = False
        #: book the energy balance (the work integrals of every phase, ``Result.energy``); off, the result's energy
        #: record is empty and the states and events are the same, bit for bit (the shooting method's flows: no
        #: periodic code reads it, and its integrals cost about a tenth of a crack period). The state's overflow
        #: guards stay (non-finite outputs, a non-finite state at a phase's end: :func:`.guard.overflow`); only the
        #: balance's own (its integrals overflowing while the state is finite) goes with it
        self.energy_balance = bool(energy_balance)
        if configurations is not None:   # kept in (and shared through) the caller's store: :meth:`kept`
            if not isinstance(configurations, dict) or configurations.get("system", system) is not system:
                raise NsfemError("configurations: a store must be a dict, empty or kept by an integrator of the same "
                                 "system (another system's configurations are not this one's)")
            self.keep_configurations = True
            self._cache, self._systems, self._gaps = (configurations.setdefault(k, {}) for k in
                                                      ("modes", "systems", "gaps"))
            configurations.setdefault("system", system)

    def kept(self) -> dict:
        """The configurations this integrator keeps between runs, as a store another integrator of the same system
        takes (``configurations``; :meth:`nsfem.periodic.flow.FlowMap.share`): {"system", "modes", "systems",
        "gaps"}; empty unless ``keep_configurations``."""
        if not self.keep_configurations or self._rings:
            return {}
        return {"system": self._polygon, "modes": self._cache, "systems": self._systems, "gaps": self._gaps}

    def configuration(self, mode: Mode) -> Configuration:
        mode = mode.dynamics
        key, turn = mode, ()
        if self._rings:   # a closed facet of a turned ring: the configuration of its turn
            closed = set(mode.closed)
            turn = tuple(r.signature() for r in self._rings if any(j in closed for j in r.facets))
            key = (mode, turn)
        if key not in self._cache:
            if self._rings and len(self._cache) >= self.max_configurations:   # turned ones: keep the recent
                for old in list(self._cache)[: self.max_configurations // 2]:
                    del self._cache[old]
                self._systems.clear()
            self._cache[key] = self._build(mode, turn)
        cfg = self._cache[key]
        if cfg.system is not self.system:
            # no closed facet of a turned ring: the same equations; its rows read the turned facets' gaps
            cfg = copy.copy(cfg)
            cfg.system = self.system
            cfg.__dict__.pop("_rows_plans", None)   # the old system's gap rows (events.event_rows)
            self._cache[key] = cfg
        return cfg

    def _build(self, mode: Mode, turn: tuple) -> Configuration:
        """A new configuration (``turn``: the round rings' turns it is of); an elastic ring's law whose matrices an
        earlier configuration has (the same :func:`.configuration.matrix_key`: a facet alone at a corner is its
        edge's law, the corners' laws of both facets differ in their load alone) shares that one's decompositions
        (:meth:`Configuration.with_load`): the same arrays, bit for bit, without another eigen-decomposition."""
        if not mode.ring:
            return Configuration(self.system, mode)
        same = (matrix_key(self.system, mode), turn)
        base = self._systems.get(same)
        if base is None or base.system is not self.system:
            base = self._systems[same] = Configuration(self.system, mode)
            return base
        return base.with_load(mode)

    def _turn(self) -> None:
        """The system of the round rings' turns now."""
        from dataclasses import replace

        self.system = replace(self._polygon, contacts=turned(self._polygon.contacts, self._rings))

    def _phase(self, mode: Mode, t: float, q: np.ndarray, v: np.ndarray) -> Phase:
        """The phase of configuration ``mode`` from (t, q, v); sticking slips held at their value."""
        cs = self.system.contacts
        if mode.stick or mode.edge:
            g0 = np.concatenate([cs.jN[list(mode.closed)]] + [-(cs.JS[k].T @ q) for k in mode.stick]
                                + [[-(cs.facet(k, i)[1] @ (cs.JS[k].T @ q))] for k, i in mode.edge])
        else:   # the closed gaps' constants alone: the same for every phase of the mode (formed once per contacts)
            hit = self._gaps.get(mode)
            if hit is None or hit[0] is not cs:
                hit = self._gaps[mode] = (cs, cs.jN[list(mode.closed)] if mode.closed else np.zeros(0))
                hit[1].flags.writeable = False
            g0 = hit[1]
        return Phase(self.configuration(mode), t, q, v, g0)

    def _advance(self, phase: Phase, rows: Rows, t0: float, t1: float):  # pragma: no cover - abstract
        """(Event or None, xi(t) callable valid on [t0, t_event or t1])."""
        raise NotImplementedError

    def run(self, t_end: float, output_dt: float, q0=None, v0=None, *, t_start: float = 0.0) -> Result:
        """The motion from (q0, q0') at ``t_start`` [s] (the state's time on the forcing's clock; default 0) to
        ``t_end``, sampled every ``output_dt`` from ``t_start``: every time of the run (outputs, events) on that
        clock. A start other than 0 runs the same system (its configurations kept where ``keep_configurations``)
        at another forcing phase: a shooting's section (:class:`nsfem.periodic.flow.FlowMap`)."""
        if not (isinstance(t_start, (int, float, np.integer, np.floating)) and not isinstance(t_start, (bool, np.bool_))
                and math.isfinite(t_start) and t_start < t_end):
            raise NsfemError(f"t_start must be a finite number of seconds before t_end = {t_end!r}, got {t_start!r}")
        t_start = float(t_start)
        self.system = self._polygon
        self._rings = round_rings(self.system.contacts, self.system.info.get("round_rings", ())) \
            if self.round_rings else ()
        if not (self.keep_configurations and not self._rings):
            self._cache, self._systems, self._gaps = {}, {}, {}
        sysm = self.system
        cs = sysm.contacts
        n, m = sysm.n, cs.m
        if t_start:   # the grid of a run from 0 over t_end - t_start, moved to start at t_start
            t_out = t_start + output_times(t_end - t_start, output_dt)
            t_out[-1] = t_end
        else:
            t_out = output_times(t_end, output_dt)
        t_list = t_out.tolist()
        close_rows: dict = {}   # the gap rows of each list of row kinds met (_close_rows)
        q, v = initial_state(sysm, q0, v0)
        wall0 = time.perf_counter()
        Mf = factorize(sysm.M, "the mass matrix M")
        K = 0.5 * (sysm.Q + sysm.Q.T)
        P = 0.5 * (sysm.Q - sysm.Q.T)
        D = 0.5 * (sysm.C + sysm.C.T)
        K_out = len(t_out)
        out = {"q": np.zeros((n, K_out)), "v": np.zeros((n, K_out)), "gap": np.zeros((m, K_out)),
               "normal_force": np.zeros((m, K_out)), "tangential_force": np.zeros((m, 2, K_out)),
               "state": np.zeros((m, K_out), dtype=np.int8)}
        filled = 0
        events, impacts = [], []
        memory = Memory(np.zeros(m), np.zeros(m, dtype=int), self.zeno, gap_floor=cs.gap_floor)
        rings = sysm.rings
        energy = {"initial_J": 0.5 * float(v @ sysm.M @ v + q @ K @ q) + potential(rings, q), "work_external_J": 0.0,
                  "dissipated_damping_J": 0.0, "work_circulatory_J": 0.0, "dissipated_friction_J": 0.0,
                  "work_spin_J": 0.0, "lost_in_impacts_J": 0.0}
        e_max = abs(energy["initial_J"])
        book = self.energy_balance
        progress = Progress(t_end, self.progress)
        self._report = lambda t_now: progress(t_now, len(events))  # noqa: E731 - long phases report too
        completed, failure = True, None
        t = t_start
        closed_time, covered = 0.0, 0.0   # time with at least one contact closed, of the time integrated
        guard = EventGuard(cs, t_end, self.max_events, self.zeno, [r.label for r in rings])
        ring_load = (lambda v_, q_: generalized_force(rings, q_, v_)) if rings else None
        phase, phase_integrated = None, False
        try:
            v_start = v
            mode, v, imp = resolve(sysm, Mf, t, q, v, Mode(), memory,
                                   extra_load=None if ring_load is None else lambda v_, q_=q: ring_load(v_, q_))
            mode = with_rings(mode, *initial_rings(rings, q, v))
            mode = hold_degenerate(mode, lambda md, q_=q, v_=v: self._phase(md, t_start, q_, v_), memory, cs, v)
            if self._rings:
                conform(self._rings, mode.closed, q)
            if imp:
                impacts.append(imp)
                if book:
                    _impact_energy(energy, imp)
            trace = self.trace
            if trace is not None:
                trace.append({"start": True, "t": t, "q": q, "v": v_start, "v_plus": v, "impact": imp, "after": mode,
                              "system": sysm})
            while True:
                phase = self._phase(mode, t, q, v)
                phase_integrated = False
                check_phase(phase, t, t_end, mode)
                rows = event_rows(phase, mode)
                if self._rings:
                    rows = _with_wedges(rows, self._rings, mode, phase)
                ev, xi_fun = self._advance(phase, rows, t, t_end)
                t_next = t_end if ev is None else ev.t
                # outputs in [t, t_next) (and t_end at the end)
                # (t_out is sorted: those times are the indices from the first >= t to the last < t_next, or
                # <= t_end at the end)
                hi = bisect_right(t_list, t_end) if ev is None else bisect_left(t_list, t_next)
                sel = np.arange(max(bisect_left(t_list, t), filled), hi)
                if sel.size:
                    xi_out = xi_fun(t_out[sel])
                    ok = _finite_prefix(xi_out)
                    if ok < sel.size:  # the state overflows within this phase: keep the outputs before
                        if ok:
                            self._outputs(phase, mode, xi_out[:, :ok], sel[:ok], out)
                            filled = int(sel[ok - 1]) + 1
                        raise overflow(float(t_out[sel[ok]]), mode, sysm)
                    self._outputs(phase, mode, xi_out, sel, out)
                    memory.observe(cs, phase.q_map() @ xi_out, phase.v_map() @ xi_out)
                    filled = int(sel[-1]) + 1
                if xi_fun == phase.xi:
                    q_end, v_end = phase.state_at(t_next)
                else:
                    xi_end = xi_fun(t_next)
                    q_end, v_end = phase.q_map() @ xi_end, phase.v_map() @ xi_end
                if book:
                    with np.errstate(over="ignore", invalid="ignore"):  # overflow: judged just below
                        e_max = max(e_max, self._energy(phase, mode, xi_fun, t, t_next, K, P, D, energy,
                                                        ends=(q, v, q_end, v_end)))
                    # (a finite sum has no non-finite term; an overflowing one is judged term by term)
                    if not (math.isfinite(e_max) and (math.isfinite(sum(energy.values()))
                                                      or all(math.isfinite(x) for x in energy.values()))):
                        raise overflow(t_next, mode, sysm, "energy")
                phase_integrated = True
                if mode.closed or mode.ring:
                    closed_time += t_next - t
                covered = t_next - t_start
                q, v = q_end, v_end
                if trace is not None:
                    trace.append({"phase": phase, "rows": rows, "mode": mode, "t0": t, "t1": t_next, "q": q, "v": v,
                                  "event": ev})
                check_state(t_next, q, v, mode, sysm)
                progress(t_next, len(events))
                if ev is None:
                    break
                if not ev.rows:  # rk: a restart of the same configuration
                    guard.record(t, t_next, (), (), None)
                    t = t_next
                    continue
                if len(events) >= self.max_events:
                    raise NsfemError(f"more than {self.max_events} events before t = {t_next:.6g} s")
                before = mode
                touching = {rows.contacts[i] for i in ev.rows if rows.kinds[i] == "close"}
                gap_tol = np.zeros(m)
                if ev.tol is not None:
                    i_close, k_close = _close_rows(rows, close_rows)
                    gap_tol[k_close] = ev.tol[i_close]
                # slipping: contacts whose force leaves the cone at a generator (they slide on it);
                # facets: contacts whose force reached a polygon facet (stick limit) or whose slip
                # velocity reached a facet normal (turn): LCP (29) decides facet or vertex
                # stopped: contacts whose slip stopped (a 1-D slip reversing, a slip on a facet's
                # normal reaching zero): the stick test decides, whatever round-off is left of the slip
                slipping, facets, stopped = {}, {}, set()
                lam = None
                for i in ev.rows:
                    kind, k, det = rows.kinds[i], rows.contacts[i], rows.detail[i]
                    if kind == "vertex":
                        slipping[k] = det
                    elif kind == "turn" and det is None:
                        stopped.add(k)
                    elif kind in ("slip", "turn") and det is not None:
                        facets[k] = (det, kind)
                    elif kind == "slip":  # 1-D tangent: the force leaves at one end
                        if lam is None:
                            lam = phase.force_map() @ xi_fun(t_next)
                            idx = {key: j for j, key in enumerate(phase.config.rows)}
                        slipping[k] = 0 if lam[idx[("tangent", k, 0)]] > 0 else 1
                # a gap that re-closes without having risen above its zero band: the rebound is
                # below resolution, the impact sequence has accumulated (plastic impact)
                settled = {rows.contacts[i] for j, i in enumerate(ev.rows)
                           if rows.kinds[i] == "close" and ev.in_band is not None and ev.in_band[j]}
                if self._rings:
                    fired = {rows.detail[i][0]: (rows.contacts[i], rows.detail[i][1]) for i in ev.rows
                             if rows.kinds[i] == "round_turn"}
                    for i_r, (k, d) in fired.items():   # the facet turns with the contact point: a plastic impact
                        turn(self._rings[i_r], self._rings[i_r].facets.index(k), q, d)
                        settled.add(k)
                    if relax(self._rings, before.closed, touching, q) or fired:
                        self._turn()
                        sysm, cs = self.system, self.system.contacts
                        memory.lcp_cache = type(memory.lcp_cache)()
                mode, v, imp = resolve(sysm, Mf, t_next, q, v, before, memory, touching, gap_tol, slipping,
                                       settled, facets, stopped,
                                       None if ring_load is None else lambda v_, q_=q: ring_load(v_, q_))
                if rings:
                    fired = [(rows.kinds[i], rows.detail[i]) for i in ev.rows if rows.kinds[i].startswith("ring_")]
                    state = after_event(rings, before, fired, q, v, t_next)
                    if imp:
                        state = after_impact(rings, *state, q, v, t_next)
                    mode = with_rings(mode, *state)
                if memory.degenerate:   # (else nothing to hold)
                    mode = hold_degenerate(mode, lambda md, t_=t_next, q_=q, v_=v: self._phase(md, t_, q_, v_),
                                           memory, cs, v)
                if self._rings:
                    conform(self._rings, mode.closed, q)
                if imp:
                    impacts.append(imp)
                    if book:
                        _impact_energy(energy, imp)
                if trace is not None:
                    trace[-1].update(v_plus=v, after=mode, impact=imp, system=sysm, before=before)
                events.append({"t": t_next, "kinds": sorted({rows.kinds[i] for i in ev.rows}),
                               "contacts": sorted({int(rows.contacts[i]) for i in ev.rows}),
                               "graze": bool(any(ev.graze)), "impact": imp is not None,
                               "before": before.describe(), "after": mode.describe()})
                if imp and "set_closure" in imp:   # an alternating accumulation resolved as one impact
                    events[-1]["set_closure"] = imp["set_closure"]
                guard.record(t, t_next, events[-1]["kinds"], events[-1]["contacts"], imp)
                t = t_next
        except (KeyboardInterrupt, NsfemError) as exc:
            completed = False
            failure = exc if isinstance(exc, NsfemError) else None
            # the part of the current phase already searched has no event: keep its outputs
            until = getattr(phase, "searched_until", None)
            if phase is not None and not phase_integrated and until is not None and until > phase.t0:
                sel = np.flatnonzero((t_out >= phase.t0) & (t_out <= until))
                sel = sel[sel >= filled]
                if sel.size:
                    xi_out = phase.xi(t_out[sel])
                    ok = _finite_prefix(xi_out)
                    sel, xi_out = sel[:ok], xi_out[:, :ok]
                if sel.size:
                    self._outputs(phase, mode, xi_out, sel, out)
                    filled = int(sel[-1]) + 1
                    q, v = phase.q_map() @ xi_out[:, -1], phase.v_map() @ xi_out[:, -1]
                    # the work integrals follow the state to the last output
                    if book:
                        e_max = max(e_max, self._energy(phase, mode, phase.xi, phase.t0, float(t_out[sel[-1]]), K,
                                                        P, D, energy))
                    covered = float(t_out[sel[-1]]) - t_start
                    if mode.closed or mode.ring:
                        closed_time += covered + t_start - phase.t0
        finally:
            progress.close()
        if book:
            close_energy(energy, 0.5 * float(v @ sysm.M @ v + q @ K @ q) + potential(rings, q), e_max)
        else:
            energy = {}
        k = filled if not completed else K_out
        if self._rings:
            self.system = self._polygon
        res = Result(self.name, t_out[:k], out["q"][:, :k], out["v"][:, :k], out["gap"][:, :k],
                     out["normal_force"][:, :k], out["tangential_force"][:, :, :k], out["state"][:, :k],
                     events, impacts, energy, time.perf_counter() - wall0, float(t_out[k - 1]) if k else 0.0,
                     completed, {**{kk: vv for kk, vv in sysm.info.items() if kk == "ndof_full"},
                                 "configurations": len(self._cache),
                                 # of them, those that decomposed their matrices (the others share them)
                                 "decompositions": len({id(c.eigenvalues) for c in self._cache.values()}),
                                 # exact in time (between events), not sampled at the outputs
                                 "closed_fraction": closed_time / covered if covered > 0.0 else 0.0})
        if self._rings:
            res.info["round_rings"] = {r.label: {"delta_rad": min(r.delta, DELTA), **r.history} for r in self._rings}
        if failure is not None:
            res.info["error"] = str(failure)
            raise IntegrationError(str(failure), res) from failure
        return res

    # ------------------------------------------------------------------------------
    def _outputs(self, phase: Phase, mode: Mode, xi: np.ndarray, sel: np.ndarray, out: dict) -> None:
        cs = self.system.contacts
        q, v = phase.q_map() @ xi, phase.v_map() @ xi
        out["q"][:, sel], out["v"][:, sel] = q, v
        out["gap"][:, sel] = cs.gaps(q)
        if self._rings and self.system is not self._polygon:   # turned rings: on the scene's polygon
            self._contact_outputs(phase, mode, xi, sel, out)
            parts = [out[key][..., sel] for key in ("gap", "normal_force", "tangential_force", "state")]
            polygon_outputs(self._rings, self._polygon.contacts, q, *parts)
            for key, part in zip(("gap", "normal_force", "tangential_force", "state"), parts):
                out[key][..., sel] = part
            return
        self._contact_outputs(phase, mode, xi, sel, out)

    def _contact_outputs(self, phase: Phase, mode: Mode, xi: np.ndarray, sel: np.ndarray, out: dict) -> None:
        """The closed contacts' gaps (0), forces and states at the columns ``sel``."""
        cs = self.system.contacts
        if not mode.closed:
            return
        lam = phase.force_map() @ xi
        idx = {key: i for i, key in enumerate(phase.config.rows)}
        slide, edge = dict(mode.slide), dict(mode.edge)
        for k in mode.closed:
            out["gap"][k, sel] = 0.0  # held by the constraint (round-off shown as 0)
            lamN = lam[idx[("normal", k, 0)]]
            out["normal_force"][k, sel] = lamN
            if k in mode.stick:
                out["state"][k, sel] = 1
                for j in range(cs.JS[k].shape[1]):
                    out["tangential_force"][k, j, sel] = lam[idx[("tangent", k, j)]]
            else:
                out["state"][k, sel] = 2
                if k in slide:
                    e = cs.generators(k)[:, slide[k]]
                    for j in range(e.size):
                        out["tangential_force"][k, j, sel] = cs.mu[k] * lamN * e[j]
                elif k in edge:
                    n_f, t_f, c, _ = cs.facet(k, edge[k])
                    s_f = lam[idx[("tangent", k, 0)]]
                    for j in range(2):
                        out["tangential_force"][k, j, sel] = cs.mu[k] * c * lamN * n_f[j] + s_f * t_f[j]

    def _energy(self, phase, mode, xi_fun, t0, t1, K, P, D, energy, ends=None) -> float:
        """Add the work integrals over [t0, t1]; return max E seen (at the evaluation points).
        ``ends``: (q, q') at t0 and at t1 when the caller has them (the closed form then evaluates E there).

        For ``exact`` on the modal path the integrals are quadratic forms of sums of exponentials and
        divided differences (resonance, rigid bodies), integrated in closed form (:meth:`_energy_terms`);
        without a modal form (the matrix exponential's path), Gauss-Legendre on segments of 16 sampling
        steps with nodes enough for the fastest term to 1e-17; for ``rk``, 4-point Gauss-Legendre on the
        sampling grid.
        """
        if t1 <= t0:
            return 0.0
        sysm = self.system
        cs = sysm.contacts
        # the stored energy a ring's law does not hold goes to its damper (module ring): released rings',
        # one facet's at a corner
        loose = [(sysm.rings[i], None) for i, _ in mode.latent]
        loose += [(sysm.rings[i], law) for i, law, _ in mode.ring if sysm.rings[i].place(law) != law]
        if loose:
            if ends is None:
                xs = xi_fun(np.array([t0, t1]))
                qa, qb = phase.q_map() @ xs[:, 0], phase.q_map() @ xs[:, 1]
            else:
                qa, qb = ends[0], ends[2]
            energy["dissipated_damping_J"] += sum(unheld(r, law, qa) - unheld(r, law, qb) for r, law in loose)
        if self.name == "exact":
            done = self._energy_closed_form(phase, mode, t1, K, P, D, energy, ends)
            if done is not None:
                return done
            done = self._energy_without_quadrature(phase, mode, t1, K, P, D, energy, ends)
            if done is not None:
                return done
        if self.name == "exact":
            # without the stiff modes' round-off terms (1e-13 of the state in all): they would set
            # the quadrature's step and cost, and carry no work
            xi_fun, rate = phase.pruned_xi(1e-13, t1 - t0)
            step = phase.max_step(t1 - t0, rate)
            # closed form at any time: long segments (16 sampling steps, 4 periods of the fastest
            # product of two modes) with as many Gauss nodes as make the fastest term exact to 1e-17
            nseg = max(1, math.ceil((t1 - t0) / (16.0 * step)))
            gx, gw = _gauss(_gauss_nodes(((t1 - t0) / nseg) / step * math.pi / 2.0))
        else:  # rk's dense output: 4 nodes per sampling step
            rate = None
            if sysm.schedule is not None:   # a run-up's modes move with the speed: sampled for the fastest of the ramp
                rate = self.__dict__.get("_schedule_rate")
                if rate is None:
                    rate = self._schedule_rate = sysm.schedule.fastest_rate(sysm.M, sysm.C, sysm.Q)
                rate = max(rate, phase.config.fastest_rate())
            step = phase.max_step(t1 - t0, rate)
            nseg = max(1, math.ceil((t1 - t0) / step))
            gx, gw = _GX, _GW
        edges = np.linspace(t0, t1, nseg + 1)
        h = np.diff(edges)
        ts = (edges[:-1, None] + h[:, None] * gx[None, :]).ravel()
        w = (h[:, None] * gw[None, :]).ravel()
        # one Gauss node across all segments is a uniform grid (cheap to evaluate in closed form)
        xi = np.empty((phase.dim, ts.size))
        for g in range(gx.size):
            xi[:, g::gx.size] = xi_fun(edges[:-1] + h * gx[g])
        q, v = phase.q_map() @ xi, phase.v_map() @ xi
        f = sysm.load(ts)
        energy["work_external_J"] += float(np.sum(w * np.einsum("it,it->t", f, v)))
        if np.any(D):
            energy["dissipated_damping_J"] += float(np.sum(w * np.einsum("it,it->t", v, D @ v)))
        if np.any(P):
            energy["work_circulatory_J"] += float(np.sum(w * np.einsum("it,it->t", v, P @ q)))
        if sysm.schedule is not None:   # a run-up: the work of Q(t) - Q(0) (SpeedSchedule.powers)
            circ, drive = sysm.schedule.powers(ts, q, v)
            energy["work_circulatory_J"] += float(np.sum(w * circ))
            energy["work_spin_J"] += float(np.sum(w * drive))
        for i, reg, sgn in mode.ring:
            ring = sysm.rings[i]
            u, du = ring.P @ q, ring.P @ v
            N = ring.force_rows(reg, phase.q_map(), phase.v_map(), 2 * phase.config.r) @ xi
            nu = ring.parts(reg)[2]
            energy["dissipated_damping_J"] += ring.damping * float(np.sum(w * np.sum((ring.damper(reg) @ du) ** 2, 0)))
            if ring.friction and sgn:
                RN = ROT @ N
                ws = ring.surface_speed * (ROT @ nu)[:, None] + ring.frame_spin * (ROT @ u)
                energy["dissipated_friction_J"] += ring.friction * sgn * float(np.sum(w * np.sum(RN * (du + ws), 0)))
                energy["work_spin_J"] += ring.friction * sgn * float(np.sum(w * np.sum(RN * ws, 0)))
        if mode.slide or mode.edge:
            lam = phase.force_map() @ xi
            idx = {key: i for i, key in enumerate(phase.config.rows)}
            for k, e in _friction_directions(cs, mode):
                vT = cs.JS[k].T @ v
                force = cs.mu[k] * lam[idx[("normal", k, 0)]]
                if cs.moving[k]:   # the surface's part of the slip: its work is the spin's (see close_energy)
                    off = cs.JSq[k].T @ q + cs.wS[k][:, None]
                    vT = vT + off
                    energy["work_spin_J"] -= float(np.sum(w * force * (e @ off)))
                energy["dissipated_friction_J"] -= float(np.sum(w * force * (e @ vT)))   # power <= 0
        E = 0.5 * (np.einsum("it,it->t", v, sysm.M @ v) + np.einsum("it,it->t", q, K @ q))
        return float(np.max(np.abs(E), initial=0.0))


    def _run_forms(self, K, P, D) -> tuple:
        """(K, P, D, any damping, any circulatory term, E's form diag(K, M) / 2 on (q, q')), computed once
        per run (K, P and D are the run's)."""
        forms = self.__dict__.get("_forms")
        if forms is None or forms[0] is not K or forms[1] is not P or forms[2] is not D:
            n = K.shape[0]
            H = np.zeros((2 * n, 2 * n))
            H[:n, :n], H[n:, n:] = 0.5 * K, 0.5 * self.system.M
            forms = self._forms = (K, P, D, bool(np.any(D)), bool(np.any(P)), H)
        return forms

    def _end_energy(self, phase, t1, forms, ends=None) -> tuple[float, np.ndarray]:
        """(max |E| at t0 and t1, the states (q, q') there as rows) from ``ends`` or the phase."""
        if ends is None:
            xi = phase.xi(np.array([phase.t0, t1]))
            X = np.vstack([phase.q_map() @ xi, phase.v_map() @ xi]).T
        else:
            X = np.array(ends).reshape(2, -1)      # (q, q') at t0, then at t1
        kernel = core.compiled("phase")
        if kernel is not None:
            return kernel.end_energy(forms[5], np.ascontiguousarray(X, dtype=float)), X
        E = np.einsum("ti,ti->t", X @ forms[5], X)
        return float(np.abs(E).max()), X

    def _energy_without_quadrature(self, phase, mode, t1, K, P, D, energy, ends=None):
        """The work integrals when only a constant load does work, or None: int f0 . q' dt is
        f0 . (q(t1) - q(t0)), exact; without damping, circulatory forces, sliding friction and a
        harmonic load (a non-rotating undamped structure: the axial impact of a free bar) nothing
        else is integrated, and no state is evaluated inside the phase."""
        sysm = self.system
        if mode.slide or mode.edge or mode.ring or (phase.w and (np.any(sysm.fc) or np.any(sysm.fs))):
            return None
        forms = self._run_forms(K, P, D)
        if forms[3] or forms[4]:
            return None
        e_max, X = self._end_energy(phase, t1, forms, ends)
        # from the phase's own start: the configuration's constraints hold it, the state it came from
        # may lie a gap band off them (a plastic impact located at -tol); that projection does no work
        q_start = phase.config.N @ phase.x0[: phase.config.r] + phase.qp
        energy["work_external_J"] += float(sysm.f0 @ (X[1, : sysm.n] - q_start))
        return e_max

    def _energy_closed_form(self, phase, mode, t1, K, P, D, energy, ends=None):
        """The work integrals int xi^T S xi dt of the phase in closed form, or None (no modal form).

        With xi(t) = sum_j U_j e^{mu_j (t - t0)} (:meth:`Phase.exponential_terms`, conjugate terms
        included; divided-difference groups are further terms, :meth:`_energy_terms`) each integral is
        sum_ab S_ab G_ab with G = U Phi U^T, Phi_jk = int e^{(mu_j + mu_k) s} ds:
        one G for all forms. The external work's form has nonzero columns only at the load's
        components of xi (constant, cos, sin), so without damping, circulatory or friction work
        (their forms are skipped when zero) only those columns of G are formed, from the terms
        that reach them: O(terms) work per phase instead of O(dim^3) per form. Without friction and rigid
        coordinates the forms are taken in the configuration's modal coordinates instead
        (:meth:`_energy_modal`).
        """
        forms = self._run_forms(K, P, D)
        if phase.amplitudes is not None and not (mode.slide or mode.edge or mode.ring):
            self._energy_modal(phase, t1, forms, energy)
        else:
            terms = phase.closed_form_terms()
            if terms is None:
                return None
            self._energy_terms(phase, mode, terms, t1, forms, energy)
        return self._end_energy(phase, t1, forms, ends)[0]

    def _energy_terms(self, phase, mode, terms, t1, forms, energy) -> None:
        """The work integrals from the terms (U, mu, groups) of xi (:meth:`Phase.closed_form_terms`): the
        exponentials' table by :func:`_exp_integrals`, the divided-difference columns' by
        :func:`.closed_form.group_integrals` (docs/theory.md, "The closed form of the work integrals")."""
        sysm = self.system
        cs = sysm.contacts
        Pq, Pv = phase.q_map(), phase.v_map()
        r2 = 2 * phase.config.r
        cols = [r2] + ([r2 + 1, r2 + 2] if phase.w else [])          # f(t) = F xi: f0, fc, fs there
        # kept on the configuration: it goes when the configuration cache lets it go (round rings' turns)
        hit = phase.config.__dict__.get("_ext_form")
        if hit is None or hit[0] is not sysm.f0 or hit[1] != (phase.dim, bool(phase.w)):
            F = np.column_stack([sysm.f0] + ([sysm.fc, sysm.fs] if phase.w else []))
            hit = phase.config.__dict__["_ext_form"] = (sysm.f0, (phase.dim, bool(phase.w)), Pv.T @ F)
        ext = hit[2]                                                    # the form's nonzero columns
        _, P, D, damped, circulatory, _ = forms
        # the damping form and the circulatory form's left part are the configuration's (Pv is): formed once
        parts = phase.config.__dict__.get("_work_forms")
        if parts is None or parts[0] is not forms or parts[1] != phase.dim:
            parts = phase.config.__dict__["_work_forms"] = (forms, phase.dim, Pv.T @ D @ Pv if damped else None,
                                                            Pv.T @ P if circulatory else None)
        full = []   # (key, dim x dim form)
        if damped:
            full.append(("dissipated_damping_J", parts[2]))
        if circulatory:
            full.append(("work_circulatory_J", parts[3] @ Pq))
        if mode.slide or mode.edge:
            Pf = phase.force_map()
            idx = {key: i for i, key in enumerate(phase.config.rows)}
            fric, spin = np.zeros((phase.dim, phase.dim)), np.zeros((phase.dim, phase.dim))
            for k, e in _friction_directions(cs, mode):
                force = cs.mu[k] * Pf[idx[("normal", k, 0)]]
                rate = e @ (cs.JS[k].T @ Pv)
                if cs.moving[k]:   # the surface's part of the slip rate (slip_rate_rows less S^T Pv): the spin's
                    off = e @ (cs.JSq[k].T @ Pq)
                    off[r2] += e @ cs.wS[k]
                    rate = rate + off
                    spin += np.outer(force, off)
                fric += np.outer(force, rate)
            full.append(("dissipated_friction_J", -fric))
            if np.any(spin):
                full.append(("work_spin_J", -spin))
        full += _ring_forms(sysm.rings, mode, Pq, Pv, r2)
        U, mu, groups = terms
        T = t1 - phase.t0
        if full:
            Uc, J = U, slice(None)
        else:
            Uc = U[cols]
            J = np.flatnonzero(np.any(Uc != 0.0, axis=0))
            Uc = Uc[:, J]
        kernel = core.compiled("phase")
        phi = _exp_integrals(mu, mu[J], T) if kernel is None else _compiled_exp_integrals(kernel, mu, mu[J], T)
        if groups:
            # the divided-difference columns are further terms: their integrals with the exponentials and
            # (with full forms) with each other (closed_form.group_integrals); they reach no load column
            Pe, Pg = group_integrals(mu, groups, T, pairs=bool(full)) if kernel is None else \
                _compiled_group_integrals(kernel, mu, groups, T, bool(full))
            Dg = np.hstack([D for _, D in groups])
            if full:
                phi = np.block([[phi, Pe.T], [Pe, Pg]])
                U = Uc = np.hstack([U, Dg])
            else:
                phi = np.vstack([phi, Pe[:, J]])
                U = np.hstack([U, Dg])
        G = U @ (phi @ Uc.T)      # G[:, c] = sum_jk U_j phi_jk U_ck over the columns c formed
        if full:
            energy["work_external_J"] += float(np.real(np.sum(ext * G[:, cols])))
            for key, S in full:
                energy[key] += float(np.real(np.sum(S * G)))
        else:
            energy["work_external_J"] += float(np.real(np.sum(ext * G)))

    def _energy_modal(self, phase, t1, forms, energy) -> None:
        """The work integrals in the configuration's modal coordinates z: x(t0 + s) = V z(s) with
        z = c e^{lam s} + sum_mu g_mu e^{mu s} = Z e^{nu s} (``Phase.amplitudes``, Z = [diag(c), g^T]),
        q = Vq z + q_p, q' = Vv z. The forms Vv^T D Vv, Vv^T P Vq and the load's F_mu^T Vv are the
        configuration's (formed once); per phase int z^T S z ds = sum S * (Z Phi Z^T), one m x m product for
        all forms, in which diag(c) only scales rows and columns."""
        sysm, cfg = self.system, phase.config
        c, g = phase.amplitudes
        m, r = c.size, cfg.r
        _, P, D, damped, circulatory, _ = forms
        hit = cfg.__dict__.get("_modal_forms")   # (on the configuration: it goes with it, see _energy_terms)
        if hit is None or hit[0] is not forms:
            V = cfg.eig[1]
            Vq, Vv = cfg.N @ V[:r], cfg.N @ V[r:]
            # the load at the exponents mus (0, -iw, iw), but for the phases e^{mu t0}
            loads = [sysm.f0] + ([0.5 * (sysm.fc + 1j * sysm.fs), 0.5 * (sysm.fc - 1j * sysm.fs)] if cfg.w else [])
            keys, S = [], []
            if damped:
                keys.append("dissipated_damping_J")
                S.append(Vv.T @ D @ Vv)
            if circulatory:
                keys.append("work_circulatory_J")
                S.append(Vv.T @ P @ Vq)
            # (C-ordered complex: the compiled kernel reads them as float views)
            S = np.ascontiguousarray(np.array(S, dtype=complex).reshape(len(keys), m, m))
            E = np.ascontiguousarray(np.array(loads) @ Vv, dtype=complex)
            # (and the float views the compiled kernel reads: nu, E, S)
            hit = cfg.__dict__["_modal_forms"] = (forms, E, keys, S, Vv, cfg.plan.nu[m:],
                                                  (cfg.plan.nu.view(float), E.view(float), S.view(float)))
        _, E, keys, S, Vv, mus, _ = hit
        nu = cfg.plan.nu
        kernel = core.compiled("phase")
        if kernel is not None:
            vals, PZ = _compiled_energy_modal(kernel, cfg, hit, c, g, t1 - phase.t0, phase.t0, energy)
        else:
            # Phi over the rows the forms need: the load's exponents, or all of z's (Phi is symmetric)
            Phi = _exp_integrals(nu if keys else mus, nu, t1 - phase.t0)
            if keys:
                ZP = c[:, None] * Phi[:m] + g.T @ Phi[m:]          # Z Phi
                PZ = ZP[:, m:].T                                    # rows mus of Phi Z^T
            else:
                PZ = Phi[:, :m] * c + Phi[:, m:] @ g
            energy["work_external_J"] += float(np.einsum("i,ij,ij->", np.exp(mus * phase.t0), E, PZ).real)
            if keys:
                vals = np.einsum("fjk,jk->f", S, ZP[:, :m] * c + ZP[:, m:] @ g)     # S * (Z Phi Z^T)
        if not keys:
            return
        if circulatory and phase.g0.size:   # v^T P q_p: the constant q_p (mu = 0) against every term of q'
            vals[keys.index("work_circulatory_J")] += (PZ[0] @ (Vv.T @ (P @ phase.qp))).real
        for key, val in zip(keys, vals):
            energy[key] += float(val.real)


def _compiled_energy_modal(kernel, cfg, hit: tuple, c: np.ndarray, g: np.ndarray, T: float, t0: float,
                           energy: dict) -> tuple[np.ndarray, np.ndarray]:
    """The compiled kernel ``energy_modal`` for :meth:`EventDriven._energy_modal` (its configuration's cached
    forms ``hit``): books the external work, returns (the forms' values, PZ)."""
    keys, (nu, E, S) = hit[2], hit[6]
    m, nmu = c.size, len(cfg.plan.mus)
    vals, PZ = np.empty(len(keys)), np.empty((nmu, m), dtype=complex)
    energy["work_external_J"] += kernel.energy_modal(nu, np.ascontiguousarray(c).view(float),
                                                     np.ascontiguousarray(g).view(float), T, t0, E, S, vals,
                                                     PZ.view(float))
    return vals, PZ


def _compiled_group_integrals(kernel, nu: np.ndarray, groups: list, T: float, pairs: bool):
    """:func:`.closed_form.group_integrals` by the compiled kernel ``group_integrals``."""
    Kt = sum(nodes.shape[1] for nodes, _ in groups)
    X, sizes = np.zeros((Kt, 3), dtype=complex), np.empty(Kt, dtype=np.int64)
    start = 0
    for nodes, _ in groups:         # one row per column of nodes, padded to 3
        m, K = nodes.shape
        X[start: start + K, :m], sizes[start: start + K] = nodes.T, m
        start += K
    Pe = np.empty((Kt, nu.size), dtype=complex)
    Pg = np.empty((Kt if pairs else 0, Kt), dtype=complex)
    kernel.group_integrals(np.ascontiguousarray(nu, dtype=complex), X, sizes, T, Pe, Pg)
    return Pe, (Pg if pairs else None)


def _compiled_exp_integrals(kernel, a: np.ndarray, b: np.ndarray, T: float) -> np.ndarray:
    """:func:`_exp_integrals` by the compiled kernel ``exp_integrals``."""
    phi = np.empty((a.size, b.size), dtype=complex)
    kernel.exp_integrals(np.ascontiguousarray(a, dtype=complex).view(float),
                         np.ascontiguousarray(b, dtype=complex).view(float), T, phi.view(float))
    return phi


def _exp_integrals(a: np.ndarray, b: np.ndarray, T: float) -> np.ndarray:
    """int_0^T e^{(a_j + b_k) s} ds (len(a) x len(b)): (e^{a_j T} e^{b_k T} - 1) / (a_j + b_k) (exponentials of
    the nodes, not of every pair) where |a_j + b_k| T >= 1/2; below, expm1((a_j + b_k) T) / (a_j + b_k): the
    product's absolute round-off, eps |a_j T|, would be divided by a small |a_j + b_k| (nearly cancelling
    pairs that are not conjugates: double modes, round-off real parts), and by its series
    T + T^2 x / 2 + T^3 x^2 / 6 where x = a_j + b_k is below 1e-8 / T."""
    s = np.add.outer(a, b)
    near = np.abs(s) * T < 0.5
    phi = (np.multiply.outer(np.exp(a * T), np.exp(b * T)) - 1.0) / np.where(near, 1.0, s)
    x = s[near]
    small = np.abs(x) < 1e-8 / T
    phi[near] = np.where(small, T + x * (T * T / 2.0 + x * (T * T * T / 6.0)),
                         np.expm1(x * T) / np.where(small, 1.0, x))
    return phi


def _impact_energy(energy: dict, imp: dict) -> None:
    """Book an impact: the kinetic energy it removes, less the spin's work through a frictional impulse
    against a moving surface (which may make that change a gain), is lost; the spin's work is the spin's."""
    spin = imp.get("work_spin_J", 0.0)
    energy["lost_in_impacts_J"] += imp["kinetic_before_J"] - imp["kinetic_after_J"] + spin
    energy["work_spin_J"] += spin


def _ring_forms(rings, mode: Mode, Pq: np.ndarray, Pv: np.ndarray, r2: int) -> list:
    """(key, form S) with int xi^T S xi dt the engaged rings' damper dissipation c_s |D u'|^2, friction
    dissipation mu s (R N) . (u' + w_s) and the spin's work mu s (R N) . w_s, w_s = Omega R_s R nu + Omega_f R u
    (the surface's velocity; :mod:`nsfem.contact.ring`)."""
    out = []
    for i, reg, sgn in mode.ring:
        ring = rings[i]
        U, dU = ring.P @ Pq, ring.P @ Pv
        nu = ring.parts(reg)[2]
        if ring.damping:
            a = ring.damper(reg) @ dU
            out.append(("dissipated_damping_J", ring.damping * (a.T @ a)))
        if ring.friction and sgn:
            RN = ROT @ ring.force_rows(reg, Pq, Pv, r2)
            Ws = ring.frame_spin * (ROT @ U)
            Ws[:, r2] += ring.surface_speed * (ROT @ nu)
            c = ring.friction * sgn
            out.append(("dissipated_friction_J", c * (RN.T @ (dU + Ws))))
            out.append(("work_spin_J", c * (RN.T @ Ws)))
    return out


def _with_wedges(rows: Rows, rings, mode: Mode, phase: Phase) -> Rows:
    """``rows`` and the round rings' wedge rows (:func:`.round.wedge_rows`), without the gap rows of a ring
    whose one facet is closed: within its wedge (delta < pi / F) no other facet can close before it opens."""
    closed = set(mode.closed)
    hidden = set()
    for r in rings:
        on = [j for j in r.facets if j in closed]
        if len(on) == 1:
            hidden.update(j for j in r.facets if j != on[0])
    keep = [i for i, (kind, k) in enumerate(zip(rows.kinds, rows.contacts)) if not (kind == "close" and k in hidden)]
    if len(keep) < rows.size:
        rows = Rows(rows.H[keep], [rows.kinds[i] for i in keep], [rows.contacts[i] for i in keep],
                    [rows.detail[i] for i in keep])
    H, kinds, contacts, detail = [rows.H], list(rows.kinds), list(rows.contacts), list(rows.detail)

    def add(row, kind, k, det=None):
        H.append(row[None, :])
        kinds.append(kind)
        contacts.append(k)
        detail.append(det)

    wedge_rows(rings, mode, phase.q_map(), add)
    return rows if len(kinds) == rows.size else Rows(np.vstack(H), kinds, contacts, detail)


def _close_rows(rows: Rows, memo: dict) -> tuple[np.ndarray, np.ndarray]:
    """(row indices, contacts) of the ``close`` rows (gaps) of ``rows``, once per lists of row kinds and
    contacts (a (configuration, mode)'s rows share theirs); ``memo`` keeps them by the lists' identity (and
    the lists, so no other list takes their id; rows formed per phase: the last 64)."""
    key = (id(rows.kinds), id(rows.contacts))
    hit = memo.get(key)
    if hit is None:
        pairs = [(i, k) for i, (kind, k) in enumerate(zip(rows.kinds, rows.contacts)) if kind == "close"]
        idx = np.array([i for i, _ in pairs], dtype=int), np.array([k for _, k in pairs], dtype=int)
        if len(memo) >= 64:
            memo.clear()
        hit = memo[key] = (rows.kinds, rows.contacts, idx)
    return hit[2]


def _finite_prefix(xi: np.ndarray) -> int:
    """The number of leading columns of xi that are finite (all of them unless the state overflows)."""
    bad = ~np.all(np.isfinite(xi), axis=0)
    return int(np.argmax(bad)) if bad.any() else xi.shape[1]


def _friction_directions(cs, mode: Mode):
    """(contact, d) with the sliding friction force mu lam_N d . (the part that works: on a
    facet the reaction along it does no work, the slip being along -n_f)."""
    out = [(k, cs.generators(k)[:, i]) for k, i in mode.slide]
    for k, i in mode.edge:
        n_f, _, c, _ = cs.facet(k, i)
        out.append((k, c * n_f))
    return out


class Exact(EventDriven):
    """Closed-form propagation between events (design section 6, method ``exact``)."""

    name = "exact"
    round_rings = True

    def __init__(self, system, **options):
        if system.schedule is not None:
            raise NsfemError("rotation.ramp_to_hz: the exact method integrates constant speeds (its phases are "
                             "closed-form exponentials); use method = rk, penalty or moreau")
        super().__init__(system, **options)

    def _advance(self, phase, rows, t0, t1):
        return first_event(phase, rows, t0, t1, getattr(self, "_report", None)), phase.xi


class RungeKutta(EventDriven):
    """solve_ivp between events (method ``rk``): DOP853 (default) or RK45, rtol/atol."""

    name = "rk"

    def __init__(self, system, solver: str = "DOP853", rtol: float = 1e-8, atol: float = 1e-12, **options):
        super().__init__(system, **options)
        if system.schedule is not None and system.contacts.m:
            raise NsfemError(f"rotation.ramp_to_hz: rk integrates a run-up of a rotor whose contacts are elastic rings "
                             f"(stator stiffness > 0) or none; {system.contacts.labels[0]} is a rigid contact, whose "
                             "constraint forces its events read at constant speed: use method = penalty or moreau "
                             "(a stator may instead be given a stiffness)")
        if system.schedule is not None and any(r.friction for r in system.rings):
            raise NsfemError(f"rotation.ramp_to_hz: {system.rings[0].label} has friction against the shaft surface, "
                             "which slides at Omega(t) r in a run-up: not modelled for a changing speed; set its "
                             "friction to 0")
        if solver not in ("DOP853", "RK45"):
            raise NsfemError(f"rk solver must be DOP853 or RK45, got {solver!r}")
        if not (0 < rtol < 1) or not (atol > 0):
            raise NsfemError(f"rk tolerances must satisfy 0 < rtol < 1 and atol > 0, got {rtol}, {atol}")
        self.solver, self.rtol, self.atol = solver, rtol, atol
        #: the bands and arming of the phase that ended in a restart (an ``up`` or ``top`` event):
        #: (config, t, H, tol, tol_d, thr, armed); the next phase, if it is that restart, continues them
        self._carry = None

    def run(self, t_end, output_dt, q0=None, v0=None, *, t_start: float = 0.0):
        self._carry = None
        self.__dict__.pop("_schedule_rate", None)
        return super().run(t_end, output_dt, q0, v0, t_start=t_start)

    def _advance(self, phase, rows, t0, t1):
        from scipy.integrate import solve_ivp  # here: scipy.integrate costs 0.1 s of every command's start

        r2 = 2 * phase.config.r
        A_aug = phase.A_aug
        xi0 = phase.xi(t0)
        harm = phase._harmonics

        if r2 == 0:
            return first_event(phase, rows, t0, t1), phase.xi

        Ax, Af = A_aug[:r2, :r2], A_aug[:r2, r2:]
        sched = self.system.schedule

        if sched is None:
            def rhs(t, x):
                return Ax @ x + Af @ harm(t)
        else:   # a run-up: the speed's change from Omega_0 as a force on the configuration's equations
            B = phase.config.B
            Pq, Pv = phase.q_map(), phase.v_map()
            steady = self.system.steady_load

            def rhs(t, x):
                xi = np.concatenate([x, harm(t)])
                p = sched.load(t) - steady(t) + sched.force(t, Pq @ xi, Pv @ xi)
                return Ax @ x + Af @ harm(t) + B @ p

        H = rows.H
        Hd = H @ A_aug
        h0 = H @ xi0
        carry, self._carry = self._carry, None
        if (carry is not None and carry[0] is phase.config and carry[1] == t0 and carry[2].shape == H.shape
                and np.array_equal(carry[2], H)):
            # a restart of the same configuration (rk stops at the maximum of an unarmed row or where
            # it leaves its band upwards, exact does not): the same phase continued, with its bands,
            # thresholds and arming. Re-deriving them from the restart state would read a row that
            # has just risen above its band (to 2 tol) back inside it: a gap of 4e-19 m re-evaluated
            # from a state of 1e-3 m is round-off, and the same up event fired again and again.
            tol, tol_d, thr, armed = (np.array(a) for a in carry[3:])
            # a row that the restart reads at or below its threshold (round-off of re-reading the
            # state, up to the band on an ill-conditioned modal basis) fires once it has gone down by
            # tol from there: a sign change from its start would never come (armed rows: below 0)
            low = (armed & (h0 <= 0.0)) | (h0 <= thr)
            thr = np.where(low, np.minimum(np.where(armed, 0.0, thr), h0 - tol), thr)
        else:
            # the band of each row as in exact: the size of its terms over the first sampling step
            step = phase.max_step(math.inf)
            window = min(step, t1 - t0) if math.isfinite(step) else t1 - t0
            xis = phase.xi(t0 + window * np.linspace(0.0, 1.0, 9))
            scale = np.max(np.abs(H) @ np.abs(xis), axis=1) + 1e-300
            tol = np.maximum(1e-11 * scale, round_off(H, xis, r2))
            armed = h0 > tol
            # as in exact: an unarmed row fires by going down by tol from where it starts, and is
            # armed at its first maximum (the phase restarts there: a rebound can be shorter than
            # a step, and solve_ivp sees only sign changes between steps)
            thr = np.where(armed, 0.0, np.minimum(-tol, h0 - tol))
            tol_d = 1e-11 * np.max(np.abs(Hd) @ np.abs(xis), axis=1) + 1e-300
        # solve_ivp sees only sign changes between its steps: a row that dips below its threshold and comes
        # back within one step is never seen (the runup scene's elastic seal at rtol 1e-8: 237 of 610 ring
        # events found, energy residual 5.4e-3, the rub's closed share 18 % instead of 47 %). Its steps are
        # held to exact's sampling step, 1/8 of the configuration's fastest period (:meth:`Phase.max_step`)
        max_step = phase.max_step(t1 - t0)
        funcs, kinds = [], []
        for i in range(rows.size):
            def ev(t, x, i=i):
                return float(H[i, :r2] @ x + H[i, r2:] @ harm(t)) - thr[i]
            ev.terminal, ev.direction = True, -1
            funcs.append(ev)
            kinds.append(("row", i))
        hd0 = Hd @ xi0
        n_rows = len(funcs)
        tops = list(np.flatnonzero(~armed & (hd0 > tol_d)))  # rising from its band: stop at the top
        ups = list(np.flatnonzero(~armed))
        for _ in range(4 * rows.size + 8):
            funcs, kinds = funcs[:n_rows], kinds[:n_rows]
            for i in ups:  # leaving the band upwards (a slow rise): restart armed
                def up(t, x, i=i):
                    return float(H[i, :r2] @ x + H[i, r2:] @ harm(t)) - 2.0 * tol[i]
                up.terminal, up.direction = True, 1
                funcs.append(up)
                kinds.append(("up", int(i)))
            for i in tops:
                def top(t, x, i=i):
                    return float(Hd[i, :r2] @ x + Hd[i, r2:] @ harm(t)) + tol_d[i]
                top.terminal, top.direction = True, -1
                funcs.append(top)
                kinds.append(("top", int(i)))
            sol = solve_ivp(rhs, (t0, t1), xi0[:r2], method=self.solver, rtol=self.rtol, atol=self.atol,
                            events=funcs or None, dense_output=True, max_step=max_step)
            if sol.status == -1:
                raise NsfemError(f"rk ({self.solver}) failed at t = {sol.t[-1]:.6g} s: {sol.message}")
            if sol.status != 1:
                break
            hits = [(te[0], j) for j, te in enumerate(sol.t_events) if len(te)]
            t_e = min(h[0] for h in hits)
            at = [kinds[j] for te, j in hits if te <= t_e + 1e-12 * max(1.0, abs(t_e))]
            soon = t_e <= t0 + 1e-12 * max(1.0, abs(t0))
            # a top at the phase start, or a band exit there that the state does not confirm, is
            # below what rk's dense output resolves: that row is not watched this phase
            early_top = [i for kind, i in at if soon and kind == "top"]
            early_up = [i for kind, i in at if soon and kind == "up"
                        and float(H[i, :r2] @ sol.sol(t_e) + H[i, r2:] @ harm(t_e)) <= tol[i]]
            # as in exact: a "crossing" of an unarmed row at the phase's start, or where the row is
            # rising, is the round-off of evaluating it near its start, not a descent by tol; the
            # row is watched from there (down by tol from its value there; up: armed)
            false_row = []
            for kind, i in at:
                if kind == "row" and not armed[i]:
                    x_e = sol.sol(t_e)
                    hd_e = float(Hd[i, :r2] @ x_e + Hd[i, r2:] @ harm(t_e))
                    if hd_e > 0.0 or (soon and hd0[i] > -tol_d[i]):
                        false_row.append(i)
                        h_e = float(H[i, :r2] @ x_e + H[i, r2:] @ harm(t_e))
                        thr[i] = min(thr[i], h_e - tol[i])
            if not (early_top or early_up or false_row):
                break
            tops = [i for i in tops if i not in early_top]
            ups = [i for i in ups if i not in early_up]
        else:
            raise NsfemError(f"rk ({self.solver}): no consistent event at t = {t0:.12g} s")

        def xi_fun(t):
            t = np.asarray(t, dtype=float)
            x = sol.sol(t)
            return np.concatenate([x, harm(t)], axis=0) if t.ndim else np.concatenate([x, harm(t)])

        if sol.status == 1:
            rows_at = [i for kind, i in at if kind == "row"]
            if not rows_at:  # a maximum of an unarmed row: restart the phase there (armed if above its band)
                x_e = xi_fun(float(t_e))
                h_e = H @ x_e
                armed = armed.copy()
                for kind, i in at:
                    if kind == "up" or h_e[i] > tol[i]:
                        armed[i] = True
                thr = np.where(armed, 0.0, thr)
                self._carry = (phase.config, float(t_e), H, tol, tol_d, thr, armed)
                return Event(float(t_e), [], []), xi_fun
            return Event(float(t_e), rows_at, [False] * len(rows_at), None,
                         [bool(not armed[i]) for i in rows_at]), xi_fun
        return None, xi_fun
