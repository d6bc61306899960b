"""Periodic orbits by shooting on the exact flow, and their Floquet multipliers.

Newton on F(x0) = phi_T(x0) - x0, x = (q, q'), with the Jacobian Phi_T - I from the monodromy
matrix (:mod:`.flow`: phase exponentials and saltation matrices). Contacts closed at the section
hold their gaps and gap rates (sticking ones their slip rates, ones whose force is on a cone's facet
their slip rate along it): the unknowns are the admissible
directions Z there (an orthonormal basis), the step the least-squares solution of
(Phi_T - I) Z dz = -F in the norm (q, q' / w), w = 2 pi / T. The Floquet multipliers are the
eigenvalues of Z^T Phi_T Z (the directions off the held constraints are removed by the plastic
impact or the held contact: their multipliers are 0).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import NsfemError
from ..integrate.base import single_threaded_blas
from ..result import Result
from .arguments import real_number, vector, whole_number
from .flow import Flow, FlowMap, near_grazing
from .neutral import NEUTRAL, neutral_multipliers, newton_step, stick_continuum, stick_positions


#: Newton steps that may grow the residual before steps must make it fall
FREE = 3
#: an event of the start's flow within this fraction of the period from the section moves the section
SECTION_MARGIN = 1e-3


@dataclass
class PeriodicOrbit:
    """A periodic orbit of period ``period_s`` through (q0, q0') at t0 (mod the period), with its stability."""

    period_s: float
    t0: float
    q0: np.ndarray
    v0: np.ndarray
    converged: bool
    residual: float
    iterations: int
    monodromy: np.ndarray
    multipliers: np.ndarray
    stable: bool
    loss: str | None
    events_per_period: int
    result: Result
    grazing: list = field(default_factory=list)
    #: events whose saltation matrix is approximate (see :class:`.flow.Flow`)
    approximations: list = field(default_factory=list)
    #: the admissible directions at the section (2n x d, orthonormal): monodromy = Z^T Phi_T Z
    directions: np.ndarray | None = None
    #: the residual after each Newton step (the first: of the start)
    history: list = field(default_factory=list)
    #: the multipliers +1 of a continuum of orbits (a contact sticking all period: :mod:`.neutral`), left out of
    #: ``stable`` and ``loss``: [{"index": into ``multipliers``, "multiplier": [re, im], "note": NEUTRAL}]
    neutral: list = field(default_factory=list)


def classify(multipliers: np.ndarray, tol: float = 1e-6) -> tuple[bool, str | None]:
    """(stable, the kind of loss): stable when every |mu| <= 1 + tol; otherwise the multiplier of largest modulus
    names it: real and positive 'fold', real and negative 'period-doubling', a complex pair 'neimark-sacker'."""
    tol = real_number("classify's tol", tol)
    if not 0.0 <= tol < 1.0:
        raise NsfemError(f"periodic: classify's tol must lie in [0, 1), got {tol}")
    try:
        mu = np.asarray(multipliers, dtype=complex).ravel()
    except (TypeError, ValueError):
        raise NsfemError(f"periodic: the Floquet multipliers must be numbers, got {str(multipliers)[:40]!r}") from None
    if not np.all(np.isfinite(mu)):
        raise NsfemError("periodic: a Floquet multiplier is not finite")
    if mu.size == 0 or np.abs(mu).max() <= 1.0 + tol:
        return True, None
    m = mu[np.argmax(np.abs(mu))]
    if abs(m.imag) > tol * abs(m):
        return False, "neimark-sacker"
    return False, "fold" if m.real > 0 else "period-doubling"


#: relative distance of period * omega / (2 pi) from an integer below which the period is a multiple of the forcing's
#: (a period computed as K / speed_hz or 2 pi K / omega is one to ~1e-15)
MULTIPLE_TOL = 1e-9


def check_forcing_multiple(system, period_s: float) -> int:
    """The number K of forcing periods in ``period_s`` (0 without harmonic forcing); NsfemError when the system is
    forced harmonically and ``period_s`` is not K >= 1 forcing periods (the flow over it is then no map of a
    periodic orbit: x0 = phi_T(x0) would not repeat)."""
    if not system.harmonic:
        return 0
    T_f = 2.0 * math.pi / system.omega
    k = period_s / T_f
    K = round(k)
    if K < 1 or abs(k - K) > MULTIPLE_TOL * max(1.0, k):
        raise NsfemError(f"periodic: the period {period_s:.10g} s is not a multiple of the forcing period {T_f:.10g} s "
                         f"(omega = {system.omega:.10g} rad/s: {k:.10g} periods); a periodic orbit of a forced system "
                         "has a period of K forcing periods")
    return int(K)


def admissible_directions(system, mode) -> np.ndarray:
    """Orthonormal basis (2n x d) of the perturbations (dq, dq') that keep ``mode``: closed gaps and their rates,
    sticking slip rates held."""
    n, cs = system.n, system.contacts
    rows = []
    for k in mode.closed:
        rows.append(np.concatenate([cs.JN[:, k], np.zeros(n)]))
        rows.append(np.concatenate([np.zeros(n), cs.JN[:, k]]))
    for k in mode.stick:
        for j in range(cs.JS[k].shape[1]):
            rows.append(np.concatenate([cs.JSq[k][:, j] if cs.moving[k] else np.zeros(n), cs.JS[k][:, j]]))
    for k, i in mode.edge:
        t = cs.JS[k] @ cs.facet(k, i)[1]
        rows.append(np.concatenate([np.zeros(n), t]))
    if not rows:
        return np.eye(2 * n)
    C = np.array(rows)
    _, s, Vt = np.linalg.svd(C)
    rank = int(np.sum(s > 1e-10 * s[0]))
    return Vt[rank:].T


def periodic_orbit(system, period_s: float, q0=None, v0=None, t0: float = 0.0, *, tol: float = 1e-9,
                   max_iter: int = 25, output_dt: float | None = None, attempts: int = 3,
                   settle_periods: int = 20, lead=None) -> PeriodicOrbit:
    """The periodic orbit of ``system`` with period ``period_s`` near (q0, q0') at t0 (module docstring).

    The section t0 moves (the orbit's ``t0`` says where to) when the flow from (q0, q0') has an event within
    SECTION_MARGIN of the period from it: the state there, a flow later, starts the shooting instead.
    Where Newton fails from (q0, q0') (a start too far for a non-smooth map), the transient goes on from there for
    ``settle_periods`` periods and Newton starts again, ``attempts`` times in all. ``converged`` says whether the
    residual |phi_T(x0) - x0| / |x0| (in (q, q' / w)) fell below ``tol``; the multipliers and the verdict are those
    of the best iterate either way. ``lead``: a :class:`.flow.FlowMap`, an exact integrator run with
    ``keep_configurations`` or its store (``configurations``; the lead transient's) whose configurations the flows
    reuse where they are theirs (:meth:`.flow.FlowMap.share`): the same orbit, without building them again."""
    n = system.n
    period_s = real_number("the period", period_s, positive=True)
    t0 = real_number("t0", t0)
    tol = real_number("tol", tol)
    if not (0 < tol < 1e-2):
        raise NsfemError(f"periodic: tol must lie in (0, 1e-2), got {tol}")
    max_iter = whole_number("max_iter", max_iter, 1)
    attempts, settle_periods = whole_number("attempts", attempts, 1), whole_number("settle_periods", settle_periods, 0)
    q, v = (np.zeros(n) if x is None else vector(x, n) for x in (q0, v0))
    if q.shape != (n,) or v.shape != (n,) or not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        raise NsfemError(f"periodic: the starting state must be two finite vectors of length {n}")
    check_forcing_multiple(system, period_s)
    with single_threaded_blas():   # (small products: a second thread waits for a core; see nsfem.integrate.blas)
        return _shoot(system, period_s, q, v, t0, tol, max_iter, output_dt, attempts, settle_periods, lead)


def _shoot(system, period_s: float, q: np.ndarray, v: np.ndarray, t0: float, tol: float, max_iter: int,
           output_dt: float | None, attempts: int, settle_periods: int, lead=None) -> PeriodicOrbit:
    """:func:`periodic_orbit` on validated arguments (its warnings name periodic_orbit's caller)."""
    n = system.n
    phi = FlowMap(system, t0, period_s, output_dt=output_dt)   # (output_dt checked there)
    if lead is not None:
        phi.share(lead)
    w = 2.0 * math.pi / period_s
    scale = np.concatenate([np.ones(n), np.full(n, 1.0 / w)])

    # a section on an event (an impact, a corner passage) makes the map non-smooth at the orbit: Newton stalls
    # there (a disk on a polygon's corner at t0: residual 6e-4 after 13 steps); the section moves to the middle of
    # the longest stretch of the period without events of the start's flow
    probe = phi(q, v)   # (with its monodromy: without a move it is the first Newton step's flow)
    # (an impact of the start itself, the start on a stop with an approaching velocity, is no event of the run but
    # lies on the section as well: its map is one-sided there)
    times = sorted(((e["t"] - t0) % period_s) for e in probe.result.events + probe.result.impacts)
    if times and min(min(times), period_s - max(times)) < SECTION_MARGIN * period_s:
        gaps = [(b - a, a) for a, b in zip(times, times[1:] + [times[0] + period_s])]
        length, after = max(gaps)
        shift = (after + 0.5 * length) % period_s
        to_section = FlowMap(system, t0, shift)
        to_section.share(phi)   # (the same forcing phase: phi's configurations)
        moved = to_section(q, v, jacobian=False)   # (its end state alone)
        q, v, t0 = moved.q, moved.v, t0 + shift
        phi = FlowMap(system, t0, period_s, output_dt=output_dt)
        phi.share(to_section)   # (a map runs its system from its section: the configurations are every section's)
        probe = None

    def run(q_, v_, fl: Flow | None = None) -> tuple[Flow, float, np.ndarray]:
        fl = phi(q_, v_) if fl is None else fl
        if not np.all(np.isfinite(fl.monodromy)):   # (an event met at a vanishing rate: its 1 / h' overflowed)
            raise NsfemError("periodic: the monodromy matrix overflowed (an event met at a vanishing rate, "
                             f"{len(fl.result.events)} events in the period): no Newton step from this state")
        F = np.concatenate([fl.q - q_, fl.v - v_])
        size = max(float(np.abs(scale * np.concatenate([q_, v_])).max()), float(np.abs(scale * F).max()), 1e-300)
        return fl, float(np.abs(scale * F).max()) / size, F

    first = run(q, v, probe)

    def newton(q, v, fl, res, F, free: int):
        """Newton's full step first, a step that grows the residual accepted up to ``free`` times (the residual of
        a non-smooth map may grow on the way: an event added or lost), then halved steps until it falls."""
        history, best, it = [res], (res, q, v, fl), 0
        while res > tol and it < max_iter:
            it += 1
            Z = _directions(system, fl)
            J = (fl.monodromy - np.eye(2 * n)) @ Z
            # (least squares; off the continuum of stick positions, if any: :mod:`.neutral`)
            W = stick_continuum(fl.monodromy, Z, _sticking(fl), scale)
            dz = newton_step(scale[:, None] * J, -scale * F, Z, W, stick_positions(system, fl.start_mode))
            dx = Z @ dz
            step, trial = 1.0, None
            for _ in range(12):
                try:   # (a step may land inside a stop: shorter ones then)
                    trial = run(q + step * dx[:n], v + step * dx[n:])
                except NsfemError:
                    trial = None
                if trial is not None and (trial[1] < res or free > 0):
                    break
                trial = None
                step *= 0.5
            if trial is None:
                break
            if trial[1] >= res:
                free -= 1
            q, v = q + step * dx[:n], v + step * dx[n:]
            fl, res, F = trial
            history.append(res)
            if res < best[0]:
                best = (res, q, v, fl)
        return best, it, history

    it, history, best = 0, [], None
    for attempt in range(attempts):
        if attempt:   # Newton failed from here: the transient goes on from its start for settle_periods first
            for _ in range(settle_periods):
                f = phi(q, v, jacobian=False)
                q, v = f.q, f.v
            first = run(q, v)
        found, k, h = newton(q, v, *first, free=FREE)
        it, history = it + k, history + h
        if found[0] > tol and FREE:   # the monotone path from the same start instead
            again, k, h = newton(q, v, *first, free=0)
            it, history = it + k, history + h
            if again[0] < found[0]:
                found = again
        if best is None or found[0] < best[0]:
            best = found
        if best[0] <= tol:
            break
    res, q, v, fl = best
    Z = _directions(system, fl)
    Mr = Z.T @ fl.monodromy @ Z
    mu = np.linalg.eigvals(Mr) if Mr.size else np.zeros(0, dtype=complex)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    W = stick_continuum(fl.monodromy, Z, _sticking(fl), scale)
    idx = neutral_multipliers(mu, W.shape[1])
    neutral = [{"index": int(i), "multiplier": [float(mu[i].real), float(mu[i].imag)], "note": NEUTRAL}
               for i in sorted(idx)]
    stable, loss = classify(np.delete(mu, idx))
    converged = res <= tol
    if not converged:
        warnings.warn(f"periodic: shooting did not converge in {it} Newton steps (residual {res:.3g} > tol {tol:g}); "
                      "the orbit and its multipliers are of the last iterate", stacklevel=3)
    if fl.approximations:
        first = fl.approximations[0]
        warnings.warn(f"periodic: {len(fl.approximations)} event(s) of the orbit have no exact saltation matrix (the "
                      f"first at t = {first['t']:.6g} s: {first['why']}); the Floquet multipliers and the verdict "
                      "are those of an approximate monodromy matrix", stacklevel=3)
    grazing = [{"contact": c, "t": g["t"], "gap_min": 0.0} for g in fl.grazing for c in g["contacts"]]
    grazing += near_grazing(fl)
    if grazing:
        worst = min(grazing, key=lambda g: g["gap_min"])
        warnings.warn(f"periodic: the orbit grazes contact {system.contacts.labels[worst['contact']]} (smallest gap "
                      f"{worst['gap_min']:.3g} m at t = {worst['t']:.6g} s without closing): near a grazing bifurcation "
                      "the Floquet multipliers do not describe nearby motions that touch", stacklevel=3)
    return PeriodicOrbit(float(period_s), float(t0), q, v, converged, res, it, Mr, mu, stable, loss,
                         len(fl.result.events), fl.result, grazing, fl.approximations, Z, history, neutral)


def _sticking(fl: Flow) -> bool:
    """Whether a contact sticks (or holds its force on a cone's facet) at the flow's section."""
    mode = fl.start_mode
    return bool(mode is not None and (mode.stick or mode.edge))


def _directions(system, fl: Flow) -> np.ndarray:
    """The admissible directions at the section of a flow: of the mode it started in."""
    return admissible_directions(system, fl.start_mode)
