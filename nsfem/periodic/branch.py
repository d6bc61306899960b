"""Branches of periodic orbits over a parameter: pseudo-arclength continuation of the shooting problem, the
stability along it, its bifurcations, and the switch onto the period-doubled branch.

The unknowns are the section state u = (q, q') and the parameter p (a rotor speed, a clearance...). The residual
r(u, p) = phi_T(p)(u; p) - u with J_u = Phi_T - I (the monodromy matrix of :mod:`.flow`: exact) and J_p by a forward
difference in p: (phi_T(u; p + h) - phi_T(u; p)) / h, h = 1e-6 of the range (at least 1e-8 |p|: DP_FLOOR), from the
flow at p the residual has anyway (one plain flow and one system more). Its error is the truncation h |phi_pp| / 2
plus the flow's noise 2 delta / h (event times and the phases' closed forms: delta ~ 3.5e-10 of the orbit's size on
the crack, from differences at h down to 1e-8 of the range); at this h both are ~1e-4 of |J_p| on the crack (12.4
Hz), as were the central differences at the same h it replaced (noise-dominated, 2e-4), which cost two plain flows
and two systems: J_p was ~60 % of a branch's time. It is formed at every residual: reused over a corrector's
iterates it made Newton linear, steps grew less often (they grow after at most two iterations) and near a grazing,
where |J_pp| grows like (p - p_g)^-3/2, the impact oscillator's branch took 44 points on its impacting side instead
of 15; the crack gained 8 % per hertz covered. J_p only steers the corrector and the predictor's tangent: the points
are zeros of the exact residual; :func:`.continuation.continue_branch` follows the branch through folds and locates
where a multiplier leaves the unit circle. The orbit's phase drifts with p, so its events move over the section,
where the section state jumps (an impact's velocity) and the map is not smooth: after each point, when an event has
come within a quarter of the longest event-free stretch of the period from the section (or a step failed at the
smallest step), the section moves to that stretch's middle (:meth:`_Problem.reanchor`, the continuation's
``reanchor``); each point keeps its section time ``t0_s``. At a period doubling the doubled orbit (period 2 T)
branches off along the eigenvector of the multiplier -1: :func:`doubled_start` solves for it a little past the
bifurcation, and the doubled branch is continued like the first.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import NsfemError
from .continuation import Branch, BranchPoint, continue_branch, critical_vector
from .flow import FlowMap, near_grazing
from .arguments import real_number, whole_number
from .neutral import deflated, stick_continuum, stick_positions
from .shooting import SECTION_MARGIN, admissible_directions, check_forcing_multiple, classify, periodic_orbit

#: the parameter step of J_p's forward difference (and of the section move's central du/dp), relative to the range
DP = 1e-6
#: ... and at least this fraction of |p| (:meth:`_Problem.jp_step`): the flow's noise (~3.5e-10 of the orbit on the
#: crack) over a step h is ~2 delta / h of J_p, so DP of a narrow range alone drowns J_p in it (crack at 12.4 Hz,
#: against h = 2e-7 Hz: 1e-3 off at h = 2e-9 Hz, 0.3 at 2e-10, 2.3 at 2e-11, 14 at 2e-12 Hz = 1.6e-13 p); at
#: 1e-8 |p| the step is that of a range of 1e-2 |p|, where J_p is as accurate as on the shipped ranges, which it
#: leaves alone (crack 12.3:12.5 Hz: 2e-7 > 1.24e-7 Hz; rub 20:22.4 Hz; the impact oscillator's 0.2 rad/s)
DP_FLOOR = 1e-8
#: the section moves (to the middle of the longest stretch of the period without events) when an event of the
#: orbit has drifted to within this share of that stretch's half from it: from the middle the phase may drift by
#: half of it before (the rub on 64 facets: a corner every 1/64 period, drifting by one per ~0.8 Hz)
RECENTER = 0.5
#: open gaps whose smallest value over the period is within this share of their range count in the margin to a
#: grazing (:meth:`_Problem.events`)
GRAZE_WATCH = 0.1
#: a closing whose approach speed (relative, as the margin's) is below this closes at rest (the crack's closings:
#: 1e-19 to 1e-16 measured, round-off of zero), which is the orbit's own structure, not a grazing approached
AT_REST = 1e-12
#: the shooting's tolerance for the first orbit past a grazing (:meth:`_Problem.solve`); the continuation corrects
#: it to its own tol after
GRAZE_SOLVE_TOL = 1e-10
#: the section moves to the middle of a stretch at least this share of the longest (the one whose time is nearest
#: t = 0): its events then lie 0.375 of the longest from it, beyond the trigger's 0.25
WIDE = 0.75


@dataclass
class OrbitPoint(BranchPoint):
    """A :class:`~.continuation.BranchPoint` of an orbit branch with its section's time [s]: u = (q, q') at t0_s."""

    t0_s: float = 0.0


@dataclass
class OrbitBranch:
    """A branch of periodic orbits: per point the parameter value, the orbit's section state and stability; the
    bifurcations located on it; the period-doubled branches switched onto (each an :class:`OrbitBranch`)."""

    key: str
    multiple: int
    points: list[dict]
    bifurcations: list[dict]
    stop: str
    reason: str
    doubled: list = field(default_factory=list)
    #: the first point's section time [s] (the start's, moved by the shooting off an event); each point has its own
    #: (``t0_s``: the section moves when an event of the orbit drifts onto it)
    t0: float = 0.0
    #: the section's moves: [{"index": the point (its state at the old section), "value", "t0_s": the new section,
    #: "forced": after a failed step, "multipliers_before", "multipliers_after": the point's at both sections}]
    reanchors: list = field(default_factory=list)

    def summary(self) -> dict:
        """The JSON of ``nsfem periodic --continue`` (design section 9): ``branch`` and ``bifurcations``."""
        return {"branch": [{k: v for k, v in p.items() if k not in ("q0", "v0")} for p in self.points],
                "bifurcations": [{k: v for k, v in b.items() if k not in ("q0", "v0")} for b in self.bifurcations],
                "stop": self.stop, "reason": self.reason, "t0_s": self.t0, "reanchors": self.reanchors,
                "doubled_branches": [d.summary() for d in self.doubled]}


class _Problem:
    """The shooting residual of a family of systems, the monodromy of the last point kept for its stability."""

    def __init__(self, system_at: Callable, period_at: Callable, t0: float, dp: float, multiple: int):
        self.system_at, self.period_at, self.t0, self.dp, self.multiple = system_at, period_at, t0, dp, multiple
        self._maps: dict = {}
        self.last = None
        #: the recent flows with their monodromy, by (p, u): the accepted point's, for moving the section
        self._flows: dict = {}
        #: the residual's rows are divided by these (the orbit's size in q, in q'): a tolerance relative to it
        self.weights = None
        #: the section time of each coordinate system (BranchPoint.anchor)
        self.t0s = [t0]

    def flow_map(self, p: float) -> FlowMap:
        fm = self._maps.get(p)
        if fm is None:
            if len(self._maps) > 8:   # the recent parameter values only (each keeps its configurations)
                self._maps.pop(next(iter(self._maps)))
            fm = self._maps[p] = FlowMap(self.system_at(p), self.t0, self.multiple * self.period_at(p))
        return fm

    def residual(self, u: np.ndarray, p: float):
        """(r, J_u, J_p) of the shooting problem at (u, p), rows divided by ``weights``: r = phi_T(u; p) - u,
        J_u = Phi_T - I (exact), J_p by :meth:`parameter_derivative`."""
        n = u.size // 2
        fl = self.flow_map(p)(u[:n], u[n:])
        end = np.concatenate([fl.q, fl.v])
        r = end - u
        Jp = self.parameter_derivative(u, p, end)
        self.last = (p, u.copy(), fl)
        if len(self._flows) > 16:
            self._flows.pop(next(iter(self._flows)))
        self._flows[(p, u.tobytes())] = fl
        D = self.weights
        return D * r, self.state_jacobian(fl), D * Jp

    def state_jacobian(self, fl) -> np.ndarray:
        """J_u = D (Phi_T - I), D = diag(weights); where a contact sticks all period (a continuum of orbits along
        static shifts: :mod:`.neutral`) deflated along them, so that the corrector's steps keep the stick positions
        (without it the bordered system is singular)."""
        D = self.weights
        J = D[:, None] * (fl.monodromy - np.eye(fl.monodromy.shape[0]))
        mode = fl.start_mode
        if mode is None or not (mode.stick or mode.edge):
            return J
        system = fl.trace[0]["system"]
        W = stick_continuum(fl.monodromy, admissible_directions(system, mode), True, D)
        return deflated(J, W, stick_positions(system, mode), D) if W.shape[1] else J

    def parameter_derivative(self, u: np.ndarray, p: float, end: np.ndarray) -> np.ndarray:
        """d phi_T(u; p) / dp (2n,) by a forward difference from ``end`` = phi_T(u; p): one plain flow at p + dp
        (module docstring: as accurate as the central difference it replaced, at half its cost)."""
        n = u.size // 2
        h = self.jp_step(p)
        f = self.flow_map(p + h)(u[:n], u[n:], jacobian=False)
        return (np.concatenate([f.q, f.v]) - end) / h

    def jp_step(self, p: float) -> float:
        """J_p's step at p: DP of the range, at least DP_FLOOR |p|, as represented ((p + h) - p: the flow at p + h is
        the flow at that value)."""
        h = max(self.dp, DP_FLOOR * abs(p))
        return (p + h) - p

    def reanchor(self, u: np.ndarray, p: float, forced: bool):
        """The continuation's change of coordinates (:func:`.continuation.continue_branch`'s ``reanchor``): when an
        event of the orbit through u at p lies within RECENTER of half the longest event-free stretch of its period
        from the section (or a step failed: ``forced``), the section moves to the middle of a long stretch (WIDE);
        returns (the state there, the flow's transition matrix to it, the state's derivative in p) or None."""
        fl = self._flows.get((p, u.tobytes()))
        n = u.size // 2
        if fl is None:
            fl = self.flow_map(p)(u[:n], u[n:])
        T = self.multiple * self.period_at(p)
        times = sorted(((e["t"] - self.t0) % T) for e in fl.result.events + fl.result.impacts)
        if not times:
            return None
        gaps = [(b - a, a) for a, b in zip(times, times[1:] + [times[0] + T])]
        longest = max(length for length, _ in gaps)
        near = min(min(times), T - max(times))
        if not forced and near >= RECENTER * 0.5 * longest:
            return None
        # the middle of a stretch of at least WIDE of the longest (its events then RECENTER-farther than the trigger)
        # whose new section time lies nearest t = 0: the state a flow of ``shift`` later is the orbit's at
        # t0 + shift - T too, and the section's forcing phase w t0 drifts with the speed by t0 dw (least near 0)
        def new_t0(shift: float) -> float:
            return self.t0 + shift - (T if shift > 0.5 * T else 0.0)

        shifts = [(after + 0.5 * length) % T for length, after in gaps if length >= WIDE * longest]
        shift = min(shifts, key=lambda x: abs(new_t0(x)))
        if forced and min(shift, T - shift) <= SECTION_MARGIN * T:
            return None   # (the section is in that middle already: the events are not what failed)
        moved = FlowMap(self.system_at(p), self.t0, shift)(u[:n], u[n:])
        # the new state's change with p at the old one (central differences at J_p's step: once per move): with the
        # flow's Jacobian it maps the branch's tangent into the new coordinates (M alone may turn it back). The new
        # section is the time
        # new_t0, which is t0 + shift - T with T the period at p: at p' the state there is the flow's over
        # shift - T + T(p') (the orbit repeats after T(p'))
        t1 = new_t0(shift)

        def duration(pp: float) -> float:
            return shift if t1 == self.t0 + shift else shift - T + self.multiple * self.period_at(pp)

        h = self.jp_step(p)
        ends = [FlowMap(self.system_at(p + s * h), self.t0, duration(p + s * h))(u[:n], u[n:], jacobian=False)
                for s in (1.0, -1.0)]
        dudp = (np.concatenate([ends[0].q, ends[0].v]) - np.concatenate([ends[1].q, ends[1].v])) / ((p + h) - (p - h))
        self.t0 = t1
        self.t0s.append(self.t0)
        self._maps.clear()
        self._flows.clear()
        return np.concatenate([moved.q, moved.v]), moved.monodromy, dudp

    def _flow(self, u: np.ndarray, p: float):
        """The flow over the period from u at p: the last residual's when it was there."""
        if self.last is not None and self.last[0] == p and np.array_equal(self.last[1], u):
            return self.last[2]
        fl = self._flows.get((p, u.tobytes()))
        if fl is None:
            n = u.size // 2
            fl = self.flow_map(p)(u[:n], u[n:])
        return fl

    def events(self, u: np.ndarray, p: float) -> tuple[tuple, float]:
        """The continuation's ``events``: the orbit's structure (its events per period, each by its contacts, kinds
        and whether it is an impact: a sorted tuple, independent of the section) and its margin to a grazing, the
        least of (a) an open gap's smallest value over the period (:func:`.flow.near_grazing`, within GRAZE_WATCH of
        its range) over that range and (b) an impact's or closing's approach speed over the gap's range times the
        frequency 2 pi / T, unless below AT_REST (a contact closing at rest: the breathing crack's, all along its
        branch); 0 at a grazing orbit, smooth on each side of it, at most 1."""
        fl = self._flow(u, p)
        res = fl.result
        structure = tuple(sorted((tuple(e["contacts"]), tuple(e["kinds"]), bool(e["impact"])) for e in res.events))
        T = self.multiple * self.period_at(p)
        gap = np.asarray(res.gap)
        reach = np.ptp(gap, axis=1) if gap.size else np.zeros(0)
        margin = 1.0
        for g in near_grazing(fl, GRAZE_WATCH):
            k = g["contact"]
            if reach[k] > 0:
                margin = min(margin, g["gap_min"] / reach[k])
        for imp in res.impacts:
            for k, speed in zip(imp["contacts"], imp["approach_m_s"]):
                if k < reach.size and reach[k] > 0:
                    rel = max(float(speed), 0.0) * T / (2 * math.pi * reach[k])
                    if rel > AT_REST:   # (a closing at rest is the orbit's own, all along the branch: no grazing)
                        margin = min(margin, rel)
        return structure, margin

    def invariant(self, u: np.ndarray, p: float) -> np.ndarray:
        """The continuation's ``invariant``: measures of the orbit that do not depend on its section, per
        coordinate its mean and root mean square over the period (the samples at output_dt over one period, each
        once: the periodic trapezoidal rule, the same sum from any section up to the sampling's error)."""
        q = np.asarray(self._flow(u, p).result.q)[:, :-1]
        return np.concatenate([q.mean(axis=1), np.sqrt((q * q).mean(axis=1))])

    def solve(self, u: np.ndarray, p: float) -> np.ndarray | None:
        """The continuation's ``solve``: the orbit at p by the shooting (:func:`.shooting.periodic_orbit`, its damped
        Newton) from u at the current section; None when it does not converge or moves the section."""
        n = u.size // 2
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            orb = periodic_orbit(self.system_at(p), self.multiple * self.period_at(p), u[:n], u[n:], self.t0,
                                 tol=GRAZE_SOLVE_TOL, attempts=1)
        if not orb.converged or orb.t0 != self.t0:
            return None
        return np.concatenate([orb.q0, orb.v0])

    def multipliers(self, u: np.ndarray, p: float) -> np.ndarray:
        _, _, fl = self.last
        Z = admissible_directions(fl.trace[0]["system"], fl.start_mode)
        mu = np.linalg.eigvals(Z.T @ fl.monodromy @ Z) if Z.shape[1] else np.zeros(0, complex)
        return mu[np.argsort(-np.abs(mu), kind="stable")]


def _points(problem: _Problem, branch: Branch, key: str) -> list[dict]:
    out = []
    for bp in branch.points:
        n = bp.u.size // 2
        mu = np.zeros(0, complex) if bp.multipliers is None else np.asarray(bp.multipliers)
        stable, loss = classify(mu) if mu.size else (True, None)
        out.append({"value": float(bp.p), key: float(bp.p),
                    "period_s": float(problem.multiple * problem.period_at(bp.p)), "converged": bool(bp.converged),
                    "residual": float(bp.residual),
                    "multipliers": [[float(m.real), float(m.imag)] for m in mu], "stable": stable, "loss": loss,
                    "section_q_max": float(np.abs(bp.u[:n]).max()), "t0_s": float(problem.t0s[bp.anchor]),
                    "q0": bp.u[:n].copy(), "v0": bp.u[n:].copy()})
    return out


def _orbit_point(problem: _Problem, bp: BranchPoint) -> OrbitPoint:
    """bp with its section's time."""
    return OrbitPoint(**{f: getattr(bp, f) for f in bp.__dataclass_fields__}, t0_s=float(problem.t0s[bp.anchor]))


def orbit_branch(system_at: Callable[[float], object], period_at: Callable[[float], float], q0, v0, p0: float,
                 p_end: float, *, key: str = "p", multiple: int = 1, t0: float = 0.0, tol: float = 1e-9,
                 step: float | None = None, max_steps: int = 100, switch: bool = True, depth: int = 1,
                 max_iter: int = 20, on_point: Callable[[object, int], None] | None = None,
                 grazing: bool = True) -> OrbitBranch:
    """Continue the orbit through (q0, q0') at p0 (period ``multiple`` T(p0)) towards p_end.

    ``system_at(p)``: the ContactSystem at parameter p; ``period_at(p)``: the forcing period there [s]. The start is
    first made an orbit at p0 (:func:`.shooting.periodic_orbit`); the section moves off events that drift onto it
    (module docstring: each point's ``t0_s``, the moves in ``reanchors``; ``on_point`` gets
    :class:`OrbitPoint` objects). With ``switch``, at each located period doubling
    the doubled branch is followed too (``depth`` levels). ``on_point(point, multiple)``: called with each
    accepted :class:`~.continuation.BranchPoint` of this branch and of the doubled ones (``multiple``: its orbit's
    period in forcing periods) as it is found."""
    try:
        p0, p_end = real_number("the continuation's start", p0), real_number("the continuation's end", p_end)
    except NsfemError:
        raise NsfemError(f"periodic: the continuation range {p0!r} to {p_end!r} must be finite and not empty") \
            from None
    if p0 == p_end:
        raise NsfemError(f"periodic: the continuation range {p0!r} to {p_end!r} must be finite and not empty")
    if not (isinstance(multiple, (int, np.integer)) and not isinstance(multiple, bool) and multiple >= 1):
        raise NsfemError(f"periodic: multiple must be an integer >= 1, got {multiple!r}")
    t0, depth = real_number("t0", t0), whole_number("depth", depth, 0)
    for name, flag in (("switch", switch), ("grazing", grazing)):
        if not isinstance(flag, (bool, np.bool_)):
            raise NsfemError(f"periodic: {name} must be True or False, got {str(flag)[:40]!r}")
    if not callable(system_at) or not callable(period_at):
        raise NsfemError("periodic: system_at and period_at must be functions of the parameter")
    for p in (p0, p_end):   # the period a multiple of the forcing's along the range (its ends checked)
        check_forcing_multiple(system_at(p), multiple * period_at(p))
    span = abs(p_end - p0)
    start = periodic_orbit(system_at(p0), multiple * period_at(p0), q0, v0, t0, tol=tol)
    if not start.converged:
        raise NsfemError(f"periodic: no orbit at {key} = {p0:g} to start the continuation from (residual "
                         f"{start.residual:.3g} > tol {tol:g})")
    t0 = start.t0   # (the shooting moves a section that lies on an event: the branch's sections are the orbit's)
    problem = _Problem(system_at, period_at, t0, DP * span, int(multiple))
    u0 = np.concatenate([start.q0, start.v0])
    w = 2 * math.pi / (multiple * period_at(p0))
    n = u0.size // 2
    size_q = max(float(np.abs(start.q0).max()), 1e-12)
    u_scale = np.concatenate([np.full(n, size_q), np.full(n, max(float(np.abs(start.v0).max()), w * size_q))])
    problem.weights = 1.0 / u_scale
    br = continue_branch(problem.residual, u0, p0, p_end, step=step, max_steps=max_steps, tol=tol,
                         stability=problem.multipliers, u_scale=u_scale, max_iter=max_iter,
                         on_point=None if on_point is None else
                         (lambda bp: on_point(_orbit_point(problem, bp), int(multiple))),
                         reanchor=problem.reanchor, events=problem.events if grazing else None,
                         invariant=problem.invariant, solve=problem.solve if grazing else None)
    bif = []
    for b in br.bifurcations:
        if b["kind"] == "grazing" and not b["located"]:
            continue   # (passed by a step: the points' events per period show it; the crack passes one per 1e-3 Hz)
        u = np.asarray(b["u"])
        bif.append({"kind": b["kind"], "value": float(b["value"]), "index": int(b["index"]),
                    "t0_s": float(problem.t0s[b.get("anchor", 0)]), "q0": u[:n].copy(), "v0": u[n:].copy()})
        if b["kind"] == "grazing":   # the events per period on the side the branch came from and on the other
            bif[-1].update({"accuracy": float(b["accuracy"]), "located": bool(b["located"]),
                            "events_per_period": [len(b["structure_before"]), len(b["structure_after"])]})
    reason = br.reason
    if br.stop == "failed" and "penetrates" in reason:
        # the section moved off the events already (re-anchored) and still a state lies beyond a contact
        reason += " (a state at the section t0 lies beyond a contact although the section was moved off the events)"
    moves = [{"index": int(r["index"]), "value": float(r["value"]), "t0_s": float(problem.t0s[r["anchor"]]),
              "forced": bool(r["forced"]),
              **{k: [[float(m.real), float(m.imag)] for m in np.asarray(r[k], dtype=complex)]
                 for k in ("multipliers_before", "multipliers_after")}} for r in br.reanchors]
    out = OrbitBranch(key, int(multiple), _points(problem, br, key), bif, br.stop, reason, t0=t0, reanchors=moves)
    if switch and depth > 0:
        for b in bif:
            if b["kind"] != "period-doubling":
                continue
            try:
                q, v, p, t_d = doubled_start(system_at, period_at, b, p_end, multiple=multiple, t0=b["t0_s"],
                                             tol=tol)
                out.doubled.append(orbit_branch(system_at, period_at, q, v, p, p_end, key=key,
                                                multiple=2 * multiple, t0=t_d, tol=tol, step=step,
                                                max_steps=max_steps, switch=switch, depth=depth - 1,
                                                on_point=on_point))
            except NsfemError as exc:
                b["switch_failed"] = str(exc)
    return out


def doubled_start(system_at, period_at, bif: dict, p_end: float, *, multiple: int = 1, t0: float = 0.0,
                  tol: float = 1e-9, offset: float = 1e-3) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(q0, q0', p, t0): an orbit of period 2 ``multiple`` T just past the period doubling ``bif`` (towards p_end, a
    fraction ``offset`` of the way), started from the bifurcating orbit plus its multiplier -1's eigenvector
    (scaled to sqrt(offset) of the orbit: the doubled orbit's distance grows like the square root of the
    parameter's distance past a flip), and checked to be a genuine period-2 orbit (not the period-1 one)."""
    p_star = float(bif["value"])
    p = p_star + offset * (p_end - p_star)
    T = multiple * period_at(p_star)
    q, v = np.asarray(bif["q0"]), np.asarray(bif["v0"])
    n = q.size
    fl = FlowMap(system_at(p_star), t0, T)(q, v)
    Z = admissible_directions(fl.trace[0]["system"], fl.start_mode)
    mu, vec = critical_vector(Z.T @ fl.monodromy @ Z, -1.0)
    d = np.real(Z @ vec)
    size = max(float(np.abs(q).max()), 1e-12)
    d *= math.sqrt(offset) * size / max(float(np.abs(d[:n]).max()), 1e-300)
    for sign in (1.0, -1.0):
        try:
            orb = periodic_orbit(system_at(p), 2 * multiple * period_at(p), q + sign * d[:n], v + sign * d[n:], t0,
                                 tol=tol, attempts=1)
        except NsfemError:
            continue
        if not orb.converged:
            continue
        half = FlowMap(system_at(p), orb.t0, multiple * period_at(p))(orb.q0, orb.v0, jacobian=False)
        if np.abs(half.q - orb.q0).max() > 1e3 * tol * size:   # a genuine period-2 orbit
            return orb.q0, orb.v0, p, orb.t0
    raise NsfemError(f"periodic: no period-doubled orbit found past the period doubling at {p_star:g}")
