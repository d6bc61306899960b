"""What happens at an event: impacts (LCP 30-32), then the transition LCP (29).

:func:`resolve` takes the state (q, q'^-) at an event time and returns the configuration
that follows and the velocity after any impact:

1. Contacts touching (g <= its round-off tolerance) are candidates. If one of them
   approaches (g' < 0 beyond round-off), the impact LCP (30-32) over the candidates that
   do not separate gives the impulses and q'^+ (Newton restitution eps, frictional impulses).
   A grazing contact (g = 0, g' = 0) never triggers an impact.
2. Candidates with g' = 0 after that are closed candidates; of those with friction, the
   ones at zero slip velocity may stick, the others slide with the friction force along
   the generator most opposing their slip velocity.
3. The transition LCP (29) on the closed candidates decides: lam_N > 0 stays closed
   (else it opens), z = 0 sticks, z > 0 slides along the generator that carries the force.
4. A contact it opens with lam_N = 0 and zero gap acceleration (degenerate: the end of a bar
   just stopped by a plastic impact, whose springs are not yet stressed) is decided by the
   first non-zero higher derivative of its gap in the new configuration: if negative, the
   contact would penetrate at once, so it stays closed (:func:`hold_degenerate`).

Impacts within a set: an impact whose impulses drive a touching contact outside its LCP (one that was
separating) into approach would be followed at once by that contact's impact, whose impulse may drive
the first back (crack-front ends, W_AB < 0). That sequence is resolved within the event: impact LCPs
(30-32) over the touching contacts that do not separate, each with its restitution, until none
approaches (plastic faces: one more stage closes the set). After ``SET_STAGES`` it is an accumulation:
the velocity is projected onto the admissible cone of all touching contacts (eps = 0; the limit of the
plastic alternation for two contacts, a plastic closure of the set for more). No stage adds energy
without friction; a stage with restitution and friction that would (Kane) ends the sequence plastically. The impact record names the contacts drawn in
(``set_closure``), the stages (``set_stages``), ``set_limit`` when closed at the limit.
docs/theory.md, "Impact accumulation over a set".

Rebounds below resolution: a contact that was touching and is lifted by another contact's
impact so slowly that its flight g'^2 / (2 |g''|) stays inside its gap's zero band stays
closed (its velocity is projected onto g' = 0, the nearest velocity in the kinetic metric;
the energy this removes counts as impact loss). Without this, an elastic layer landing on
three contacts see-saws between two of them, 1e-15 m high, every 3e-9 s. The zero band never
falls below the position resolution of the structure (``ContactSet.gap_floor``, 9e-16 m on a
1 m shaft): bands relative to the motion shrink with it, and a shaft settling from rest on a
stop (1e-8 m of motion after 45 us) otherwise see-saws between interface contacts lifted by
1e-18 m every 3e-9 s.

Impact accumulation (Zeno; eps < 1): an impact whose approach speed is below
``zeno`` times the largest approach speed of that contact's earlier impacts is treated as
plastic (eps = 0 for it), so the sequence ends in persistent contact when the transition
LCP allows it. With eps = 0.5 and zeno = 1e-8 this truncates a rigid body's sequence after
27 impacts, changing the accumulation time by 1e-8 of the first flight time. An impact whose
rebound stayed inside the gap's zero band (``in_band``, see :mod:`.events`) is plastic too:
on elastic systems this ends the sequence earlier (m q'' + k q = -F, eps = 0.5: after 17
impacts, 7e-7 s before the accumulation point at 0.134 s).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import NsfemError
from ..lcp.builders import LCPCache, _impact_parts, impact_lcp, transition_lcp
from ..lcp.pivoting import _kernels as _lcp_kernels
from ..lcp.pivoting import lemke
from ..linalg import Factorization
from . import core
from .configuration import Mode
from .problem import ContactSystem

#: relative size (to the terms that make it) below which a gap, gap rate or slip rate is zero
ZERO = 1e-10
#: approach speeds below this fraction of the contact velocities at an event are settled, not impacts
CREEP = 1e-7
#: impact stages within a set at one event (impacts driving touching contacts into approach) after which the
#: sequence is taken as an accumulation and closed plastically; finite sequences on random 2-3 contact bodies
#: (eps 0.05-1, 2927 of 3000) have a median of 1 impact, 99 % end within 8
SET_STAGES = 100


@dataclass
class Memory:
    """What transitions remember between events (per contact).

    ``gap_floor``: the smallest meaningful gap (:attr:`ContactSet.gap_floor`), a floor of every
    gap's zero band: a contact lifted below it stays closed (see micro-lifts in :func:`resolve`).
    ``gap_scale``, ``rate_scale``, ``slip_scale``: the largest size so far of the terms that
    make each contact's gap, gap rate and slip rate (|J|^T |q| + |j|, |J|^T |q'|, |S|^T |q'|).
    A value counts as zero below ZERO times these: a quantity that has just cancelled (a
    velocity after a plastic impact, a slip rate at its reversal) carries the round-off of
    the motion that led there, not of its own tiny size.
    """

    max_approach: np.ndarray
    impacts: np.ndarray
    zeno: float = 1e-8
    gap_floor: float = 0.0
    gap_scale: np.ndarray | None = None
    rate_scale: np.ndarray | None = None
    slip_scale: np.ndarray | None = None
    degenerate: list = field(default_factory=list)   # set by resolve: opened with lam_N = g'' = 0
    #: the matrix parts of the impact and transition LCPs met so far, per structure (see
    #: :func:`~nsfem.lcp.builders.contact_lcp`): a run meets the same few again and again
    lcp_cache: LCPCache = field(default_factory=LCPCache, repr=False)
    _abs: tuple | None = field(default=None, repr=False)
    _abs_system: tuple | None = field(default=None, repr=False)
    _slip: tuple | None = field(default=None, repr=False)
    _kernel: tuple | None = field(default=None, repr=False)
    _impact: tuple | None = field(default=None, repr=False)

    def abs_parts(self, cs) -> tuple:
        """(|J_N|, |j_N|, [|S_k| or None]) of the contact set (formed once per set)."""
        if self._abs is None or self._abs[0] is not cs:
            aS = [np.abs(S) if S.shape[1] else None for S in cs.JS]
            self._abs = (cs, np.abs(cs.JN), np.abs(cs.jN), aS, any(S is not None for S in aS))
        return self._abs[1:4]

    def kernel_arrays(self, cs) -> tuple:
        """(J_N^T, |J_N|^T, j_N, |j_N|) C-contiguous for the compiled kernels (formed once per set)."""
        if self._kernel is None or self._kernel[0] is not cs:
            aJ, aj = self.abs_parts(cs)[:2]
            self._kernel = (cs, *(np.ascontiguousarray(a, dtype=float) for a in (cs.JN.T, aJ.T, cs.jN, aj)))
        return self._kernel[1:]

    def impact_path(self, system, Mf, kernel):
        """The compiled impact path (``kernel.ImpactPath``) of the system with the factorization Mf of its M
        (formed once per pair: it keeps the impact LCPs' matrix parts it meets)."""
        if self._impact is None or self._impact[0] is not system or self._impact[1] is not Mf:
            cs, m = system.contacts, system.contacts.m
            JNT, aJT, jN, aj = self.kernel_arrays(cs)
            ST = _floats(np.vstack([S.T for S in cs.JS])) if m else np.zeros((0, cs.n))
            srow = np.concatenate([[0], np.cumsum([S.shape[1] for S in cs.JS], dtype=np.int64)]).astype(np.int64)
            lib = _lcp_kernels()
            path = kernel.ImpactPath(JNT, aJT, jN, aj, _floats(cs.eps), _floats(system.M), ST, srow,
                                     cs.moving.astype(np.int8), None if lib is None else lib.lemke_one,
                                     np.empty(m, dtype=np.int8), np.empty(m, dtype=np.int64), np.empty((2, m)))
            self._impact = (system, Mf, path)
        return self._impact[2]

    def observe_slip(self, cs, aq: np.ndarray, av: np.ndarray) -> None:
        """The slip scales' part of :meth:`observe` (|q|, |q'| of one state or several, as columns)."""
        sv = self._slip_terms(cs, av if av.ndim == 2 else av[:, None], aq if aq.ndim == 2 else aq[:, None])
        self.slip_scale = sv if self.slip_scale is None else np.maximum(self.slip_scale, sv)

    def _slip_terms(self, cs, av: np.ndarray, aq: np.ndarray) -> np.ndarray:
        """Per contact the largest size of its slip rate's terms over the columns of (|q|, |q'|):
        |S|^T |q'| (+ |Sq|^T |q| + |w| on a moving surface), from all contacts' rows at once."""
        if self._slip is None or self._slip[0] is not cs:
            cols = [k for k in range(cs.m) for _ in range(cs.JS[k].shape[1])]
            n = cs.n
            aS = np.hstack([np.abs(S) for S in cs.JS]) if cols else np.zeros((n, 0))
            aSq = np.hstack([np.abs(S) for S in cs.JSq]) if cols and np.any(cs.moving) else None
            aw = np.concatenate([np.abs(w) for w in cs.wS]) if cols else np.zeros(0)
            # each contact's columns are adjacent: their maximum is one reduceat per contact with any
            owners = np.array(sorted(set(cols)), dtype=int)
            starts = np.searchsorted(np.array(cols, dtype=int), owners)
            self._slip = (cs, np.array(cols, dtype=int), aS, aSq, aw, owners, starts)
        _, cols, aS, aSq, aw, owners, starts = self._slip
        sv = np.zeros(cs.m)
        if not cols.size:
            return sv
        terms = aS.T @ av
        if aSq is not None:
            terms = terms + aSq.T @ aq + aw[:, None]
        sv[owners] = np.maximum.reduceat(terms.max(axis=1), starts)
        return sv

    def abs_operators(self, system) -> tuple:
        """(|C|, |Q|) of the system (formed once per system)."""
        if self._abs_system is None or self._abs_system[0] is not system:
            self._abs_system = (system, np.abs(system.C), np.abs(system.Q))
        return self._abs_system[1:]

    def observe(self, cs, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update the scales with a state (q, q') of the run (or several, as columns); return the
        state's gap and gap-rate terms |J_N|^T |q| + |j_N|, |J_N|^T |q'| (of one column: numpy's
        matmul takes the same BLAS gemv for a column and a vector, so they are :func:`_tol`'s)."""
        aJ, aj = self.abs_parts(cs)[:2]
        aq, av = np.abs(q), np.abs(v)
        if aq.ndim == 1:   # one state: a vector product is the column's (the same gemv)
            g, gv = aJ.T @ aq + aj, aJ.T @ av
        else:              # one column is its own maximum
            G, V = aJ.T @ aq, aJ.T @ av
            g = (G[:, 0] if G.shape[1] == 1 else G.max(axis=1)) + aj
            gv = V[:, 0] if V.shape[1] == 1 else V.max(axis=1)
        self.gap_scale = g if self.gap_scale is None else np.maximum(self.gap_scale, g)
        self.rate_scale = gv if self.rate_scale is None else np.maximum(self.rate_scale, gv)
        if self.slip_scale is None or self._abs[4]:   # else it stays 0
            self.observe_slip(cs, aq, av)
        return g, gv


def _spin_work(cs, lcp, x: np.ndarray, q: np.ndarray) -> float | None:
    """The work -Lambda_T . (Sq^T q + w) of an impact LCP's frictional impulses against moving surfaces, or
    None without any."""
    if not lcp.friction.size or not np.any(cs.moving[lcp.friction]):
        return None
    return -sum(float(lt @ (cs.JSq[k].T @ q + cs.wS[k])) for k, lt in zip(lcp.friction, lcp.tangential(x))
                if cs.moving[k])


def _pushed(JN: np.ndarray, v: np.ndarray, cand, active, tv: np.ndarray, absJ: np.ndarray) -> list:
    """The touching contacts (``cand``) outside the impact LCP (``active``) that the velocity v after
    its impulses makes approach beyond the round-off of their gap rate (the larger of ``tv`` and
    the size of the terms of J_N^T v)."""
    out = [k for k in cand if k not in active]
    if not out:
        return out
    gv = JN[:, out].T @ v
    tol = np.maximum(tv[out], _tol(JN[:, out], v, absJ=absJ[:, out]))
    return [k for k, g, e in zip(out, gv.tolist(), tol.tolist()) if g < -e]


def _tol(J: np.ndarray, x: np.ndarray, const=None, absJ=None) -> np.ndarray:
    """Per column: ZERO times the size of the terms of J^T x (+ const), with a floor (``absJ``:
    |J| when the caller has it)."""
    return _band((np.abs(J) if absJ is None else absJ).T @ np.abs(x) + (0.0 if const is None else np.abs(const)))


def _band(terms: np.ndarray) -> np.ndarray:
    """ZERO times the sizes of terms, with a floor of 1e-3 ZERO times the largest (see :func:`_tol`)."""
    return ZERO * terms + 1e-3 * ZERO * float(terms.max(initial=0.0)) + 1e-300


def _bands(cs, memory: Memory, q: np.ndarray, v: np.ndarray, gap_tol, kernel=None) -> tuple:
    """(g, g', gap bands, rate bands) of the state (q, q') after observing it (:meth:`Memory.observe`):
    a gap counts as zero below the larger of ZERO times its scale, the band of its own terms, ``gap_tol``
    (per contact, or None) and the gap floor; a rate likewise without the last two. g and the gap bands as
    lists. ``kernel``: the compiled module of core part "resolve" (None: this reference)."""
    if kernel is not None and memory.gap_scale is not None and memory.rate_scale is not None \
            and _fits(cs, q, v, memory.gap_scale, memory.rate_scale, gap_tol):
        # (the kernel reads without bounds checks: other shapes take the reference, which broadcasts or refuses)
        JNT, aJT, jN, aj = memory.kernel_arrays(cs)
        out = np.empty((6, cs.m))
        kernel.state_bands(JNT, aJT, jN, aj, _floats(q), _floats(v), memory.gap_scale, memory.rate_scale,
                           _EMPTY if gap_tol is None else np.ascontiguousarray(gap_tol, dtype=float),
                           float(memory.gap_floor), out)
        memory.gap_scale, memory.rate_scale = out[0], out[1]
        memory.abs_parts(cs)   # (of this set: its last entry says whether any contact has a slip)
        if memory._abs[4]:   # the slip scales as observe forms them
            memory.observe_slip(cs, np.abs(q), np.abs(v))
        return out[2].tolist(), out[3], out[4].tolist(), out[5]
    gterms, vterms = memory.observe(cs, q, v)
    g, gv = cs.gaps(q).tolist(), cs.JN.T @ v
    tg = np.maximum(ZERO * memory.gap_scale, _band(gterms))
    if gap_tol is not None:
        tg = np.maximum(tg, gap_tol)
    tg = np.maximum(tg, memory.gap_floor).tolist()
    tv = np.maximum(ZERO * memory.rate_scale, _band(vterms))
    return g, gv, tg, tv


def _rate_bands(cs, memory: Memory, v: np.ndarray, tv: np.ndarray, kernel=None) -> tuple[np.ndarray, np.ndarray]:
    """(g', bands) of the velocity v after an impulse: the bands ``tv`` widened to the round-off of
    J_N^T v's terms (what cancelled in the impulse). ``kernel``: as in :func:`_bands`."""
    if kernel is not None and _fits(cs, v, v, tv):
        JNT, aJT = memory.kernel_arrays(cs)[:2]
        out = np.empty((2, cs.m))
        kernel.rate_bands(JNT, aJT, _floats(v), tv, out)
        return out[0], out[1]
    return cs.JN.T @ v, np.maximum(tv, _tol(cs.JN, v, absJ=memory.abs_parts(cs)[0]))


def _fits(cs, q, v, *per_contact) -> bool:
    """Whether the compiled band kernels may read these arrays: q and q' of the n coordinates, one value per
    contact in each of ``per_contact`` (None: not given)."""
    n, m = (cs.n,), (cs.m,)   # (a number or a list has no shape: the reference takes it)
    return getattr(q, "shape", None) == n and getattr(v, "shape", None) == n \
        and all(a is None or getattr(a, "shape", None) == m for a in per_contact)


_EMPTY = np.zeros(0)
#: the configuration with every contact open (a Mode is immutable: one serves every event)
_FREE = Mode()


def _floats(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


def resolve(system: ContactSystem, Mf: Factorization, t: float, q: np.ndarray, v: np.ndarray, before: Mode,
            memory: Memory, touching=(), gap_tol=None, slipping=None,
            settled=(), facets=None, stopped=(), extra_load=None) -> tuple[Mode, np.ndarray, dict | None]:
    """The configuration after an event at t, the velocity after it, and the impact record.

    ``touching`` are contacts whose gap root was just located (candidates by definition);
    ``gap_tol`` per contact the size below which a gap counts as zero (from the phase's
    scale). ``slipping`` maps contacts whose stick limit was just reached to the generator
    their friction force reached: at that instant sticking on the cone's boundary also
    solves LCP (29), but the stick force is leaving the cone, so they slide. ``settled``
    contacts re-closed after a rebound below the gap's resolution: their impact is plastic.
    ``facets`` maps contacts whose stick force reached a polygon facet (kind ``slip``), or whose
    slip velocity reached a facet's normal (``turn``), to (facet, kind): LCP (29), with the
    force's position on the facet as a bounded unknown, decides between sliding on the facet
    and on a generator (a slip that has stopped at the turn goes to the stick test instead).
    ``stopped`` contacts' slip has just stopped (a 1-D slip reversing, a slip along a facet's
    normal reaching zero): they go to the stick test, whatever round-off of the slip is left
    (read against the contact's own slip scale, a stop located within the phase's zero band
    could look like a reversal onto the opposite facet, and back, every 5e-16 s).
    ``extra_load(v)``: forces besides the system's at the velocity after any impact (elastic rings).
    The returned mode has no rings: the caller adds their state. On the compiled core an impact after
    which every contact is open runs whole in :func:`_impact_fast`; every other event runs the body below,
    which is that path's specification.
    """
    cs = system.contacts
    if cs.m == 0:
        return _FREE, v, None
    kernel = core.compiled("resolve")
    if kernel is not None and memory.gap_scale is not None and memory.rate_scale is not None:
        fast = _impact_fast(kernel, system, Mf, t, q, v, before, memory, touching, gap_tol, settled)
        if fast is not None:   # an impact after which every contact is open
            return _FREE, fast[0], fast[1]
    slipping = dict(slipping or {})
    aJ, _, aS = memory.abs_parts(cs)
    # per-contact values as lists: the loops below read each a few times (a float's compare costs
    # a tenth of a numpy scalar's; the values are the same)
    g, gv, tg, tv = _bands(cs, memory, q, v, gap_tol, kernel)
    gvl, tvl = gv.tolist(), tv.tolist()
    cand = [k for k in range(cs.m) if g[k] <= tg[k] or k in before.closed or k in touching]
    approaching = [k for k in cand if gvl[k] < -tvl[k]]
    # creeping: an approach slower than CREEP of the contact velocities in the impact LCP is
    # below what that LCP resolves (its certificate is relative to its largest entry); such a
    # contact is settled by projecting its g' onto 0 (below), not by an impact
    vscale = max([abs(gvl[k]) for k in cand]
                 + [float(np.abs(cs.slip_rate(k, q, v)).max(initial=0.0)) for k in cand if aS[k] is not None],
                 default=0.0)
    creeping = [k for k in approaching if -gvl[k] <= CREEP * vscale]
    approaching = [k for k in approaching if k not in creeping]
    impact = None
    if approaching:
        active = [k for k in cand if gvl[k] <= tvl[k]]
        eps = cs.eps.copy()
        plastic = []
        for k in approaching:
            speed = -gvl[k]
            if k in settled or (memory.impacts[k] and speed < memory.zeno * memory.max_approach[k]):
                eps[k] = 0.0
                plastic.append(k)
            memory.max_approach[k] = max(memory.max_approach[k], speed)
            memory.impacts[k] += 1
        lcp = impact_lcp(cs, Mf, v, active, memory.lcp_cache, (id(system), id(Mf), "impact", tuple(active)), eps=eps,
                         q=q)
        res = lcp.solve()
        if not res.success:
            raise NsfemError(f"impact LCP (30-32) at t = {t:.9g} s: {res.message}")
        v_new = lcp.motion(res.x)
        lamN = np.zeros(cs.m)
        lamN[active] = lcp.split(res.x)[0]
        spin = _spin_work(cs, lcp, res.x, q)
        # impacts within the set: a touching contact outside the LCP (separating) that the impulses drive into
        # approach would land at once (its flight is a gap inside the zero band) and its impulse may drive
        # another back: the impacts the event search would otherwise locate one by one, 1e-9 s apart, are
        # resolved here, each an impact LCP over the touching contacts that do not separate, with their own
        # restitution (none adds energy, see impact_lcp). Plastic faces end after one such stage (the first
        # contact, at g' = 0, takes part). A sequence still going after SET_STAGES is an accumulation: its
        # limit is taken, the velocity projected onto the admissible cone of all the touching contacts
        # (LCP 30-32 with eps = 0 over them, no energy added)
        joined, stages = [], 0
        pushed = _pushed(cs.JN, v_new, cand, active, tv, aJ)
        while pushed:
            joined += [k for k in pushed if k not in joined]
            gn = cs.JN.T @ v_new
            tn = np.maximum(tv, _tol(cs.JN, v_new, absJ=aJ))
            if stages == SET_STAGES:
                part, e_part = cand, np.zeros(cs.m)
            else:
                part = [k for k in cand if gn[k] <= tn[k]]
                e_part = cs.eps.copy()
                for k in part:
                    speed = -float(gn[k])
                    if speed <= tn[k]:
                        continue
                    if k in settled or k in plastic or (memory.impacts[k] and speed < memory.zeno * memory.max_approach[k]):
                        e_part[k] = 0.0
                        if k not in plastic:
                            plastic.append(k)
                    memory.max_approach[k] = max(memory.max_approach[k], speed)
                    memory.impacts[k] += 1
            stages += 1
            lcp = impact_lcp(cs, Mf, v_new, part, memory.lcp_cache, (id(system), id(Mf), "impact", tuple(part)),
                             eps=e_part, q=q)
            res = lcp.solve()
            if not res.success:
                raise NsfemError(f"impact LCP (30-32) over the touching contacts {part} at t = {t:.9g} s: "
                                 f"{res.message}")
            v_next = lcp.motion(res.x)
            more = _spin_work(cs, lcp, res.x, q)
            if stages <= SET_STAGES and np.any(e_part[part] > 0.0) and np.any(cs.r[part] > 0):
                # Newton's restitution with Coulomb friction is not energy-consistent (Kane's example): a stage
                # that would add kinetic energy beyond the spin's work ends the sequence, closed plastically
                t0, t1 = float(v_new @ system.M @ v_new), float(v_next @ system.M @ v_next)
                if 0.5 * (t1 - t0) > max(more or 0.0, 0.0) + 1e-12 * t0:
                    stages = SET_STAGES
                    continue
            v_new = v_next
            lamN[part] += lcp.split(res.x)[0]
            if more is not None:
                spin = more if spin is None else spin + more
            active = sorted(set(active) | set(part))
            pushed = [] if stages > SET_STAGES else _pushed(cs.JN, v_new, cand, part, tv, aJ)
        ke = 0.5 * float(v @ system.M @ v), 0.5 * float(v_new @ system.M @ v_new)
        impact = {"t": t, "contacts": list(active), "impulse_Ns": lamN[active].tolist(),
                  "approach_m_s": [-gvl[k] for k in active], "plastic": plastic,
                  "kinetic_before_J": ke[0], "kinetic_after_J": ke[1]}
        if joined:
            impact["set_closure"] = [int(k) for k in joined]
            impact["set_stages"] = stages
            if stages > SET_STAGES:
                impact["set_limit"] = True   # an accumulation, closed plastically
        if spin is not None:
            # the frictional impulse against a moving surface: its work -Lambda_T . (Sq^T q + w) is the spin's
            # (the kinetic energy may grow in the impact), the rest of the change is lost
            impact["work_spin_J"] = spin
        v = v_new
        gv, tv = _rate_bands(cs, memory, v, tv, kernel)  # what cancelled sets the round-off
        gvl, tvl = gv.tolist(), tv.tolist()
    creeping = [k for k in creeping if gvl[k] < -tvl[k]]
    if creeping:
        hold = sorted(set(creeping) | {k for k in cand if abs(gvl[k]) <= tvl[k]})
        v, impact = _settle(system, Mf, t, v, hold, creeping, impact, plastic=True)
        gv, tv = _rate_bands(cs, memory, v, tv, kernel)  # what cancelled sets the round-off
        gvl, tvl = gv.tolist(), tv.tolist()
    closed = [k for k in cand if abs(gvl[k]) <= tvl[k]]
    memory.degenerate = []
    load = None   # f(t), formed once when needed
    while True:
        stick, slide, edge = _friction_states(cs, closed, q, v, slipping, facets or {}, memory, stopped)
        # micro-lift candidates (below): touching, not closed, not impacting, lifting
        lifting = [k for k in cand if k not in closed and k not in approaching and gvl[k] > 0.0]
        if load is None and (closed or lifting):
            load = system.load(t) if extra_load is None else system.load(t) + extra_load(v)
        if closed:
            fstar = load - system.C @ v - system.Q @ q
            cs_l, extra = _facet_contacts(cs, edge)
            key = (id(system), id(Mf), "transition", tuple(closed), tuple(stick),
                   tuple(sorted((int(k), int(i)) for k, i in slide.items())),
                   tuple(sorted((int(k), int(f)) for k, f in edge.items())))
            lcp = transition_lcp(cs_l, Mf, fstar, closed, stick + sorted(edge),
                                 {k: cs.generators(k)[:, i] for k, i in slide.items()}, extra,
                                 memory.lcp_cache, key, v=v)
            res = lcp.solve()
            if not res.success:
                raise NsfemError(f"transition LCP (29) at t = {t:.9g} s: {res.message}")
            if lifting:
                acc = (cs.JN.T @ lcp.motion(res.x)).tolist()
        elif lifting:
            acc = (cs.JN.T @ Mf.solve(load - system.C @ v - system.Q @ q)).tolist()
        # micro-lifts: a touching contact that did not impact itself but is lifted (by the
        # impact of another) so slowly that its flight, g'^2 / (2 |g''|), stays inside the gap's
        # zero band is not resolved: it stays closed. (Newton rebounds of impacting contacts are
        # resolved; when too small, the event search settles them.)
        micro = [k for k in lifting if acc[k] < 0.0 and gv[k] ** 2 <= -2.0 * acc[k] * tg[k]]
        if not micro:
            break
        closed = sorted(closed + micro)
        v, impact = _settle(system, Mf, t, v, closed, micro, impact)
        gv, tv = _rate_bands(cs, memory, v, tv, kernel)  # what cancelled sets the round-off
        gvl, tvl = gv.tolist(), tv.tolist()
    if not closed:
        return _FREE, v, impact
    lamN, beta, z = lcp.split(res.x)
    mc = len(closed)
    # the size of the terms of f* (f - C q' - Q q cancels to round-off when the springs are unstressed)
    aC, aQ = memory.abs_operators(system)
    fterms = np.abs(load) + aC @ np.abs(v) + aQ @ np.abs(q)
    # per closed contact on lists (all finite: the LCP certified its solution)
    bsize = (aJ[:, closed].T @ np.abs(Mf.solve(fterms))).tolist()
    lam, bN, w = lamN.tolist(), lcp.b[:mc].tolist(), res.w[:mc].tolist()
    # lam_N counts as zero below the round-off of the terms that make it (b_j over the
    # Delassus diagonal), not only relative to the largest force: a single contact whose
    # force has just vanished must open (one release event, not a no-op one first)
    fscale = max(max(lam, default=0.0), 0.0, 1e-300)
    lam_tol = [max(1e-12 * fscale, ZERO * (s + abs(bj)) / max(abs(a), 1e-300))
               for s, bj, a in zip(bsize, bN, lcp.A.diagonal()[:mc].tolist())]
    keep = [k for j, k in enumerate(closed) if lam[j] > lam_tol[j]]
    # opened with zero force and zero gap acceleration: decided by higher derivatives later
    wsize = [s + abs(bj) + t for s, bj, t in zip(bsize, bN, (np.abs(lcp.A[:mc]) @ np.abs(res.x)).tolist())]
    top = 1e-3 * max(max(wsize, default=0.0), 0.0)
    memory.degenerate = [k for j, k in enumerate(closed)
                         if k not in keep and abs(w[j]) <= ZERO * (wsize[j] + top) + 1e-300]
    new_stick, new_slide, new_edge = [], [], []
    row = 0
    zk = dict(zip((int(k) for k in lcp.friction), z))
    betas = {}
    for k, rk in zip(lcp.friction, lcp.r):
        betas[int(k)] = beta[row:row + rk]
        row += rk
    bscale = max(float(np.abs(lcp.b).max(initial=0.0)), 1e-300) if zk else None   # (friction contacts only)
    for k in keep:
        if k in slide:
            new_slide.append((k, slide[k]))
        elif k in edge:
            f = edge[k]
            if zk[k] <= 1e-10 * bscale:   # the force stays inside the facet
                new_edge.append((k, f))
            else:                         # it leaves at a vertex: slide on that generator
                new_slide.append((k, (f + 1) % int(cs.r[k]) if betas[k][0] >= betas[k][1] else f))
        elif k in zk:
            if zk[k] <= 1e-10 * bscale:
                new_stick.append(k)
            else:
                b = betas[k]
                i = int(np.argmax(b))
                r = b.size
                if cs.JS[k].shape[1] == 2 and r >= 3:
                    j = (i + 1) % r if b[(i + 1) % r] >= b[(i - 1) % r] else (i - 1) % r
                    if b[j] > 1e-9 * b[i]:   # the force lies inside a facet: slide on it
                        new_edge.append((k, i if j == (i + 1) % r else j))
                        continue
                new_slide.append((k, i))
    rolling = [k for k in new_stick if cs.moving[k]]
    if rolling:
        raise _rolling(cs, rolling[0], t, "the slip velocity and the friction the cone allows both say so")
    mode = Mode(tuple(sorted(keep)), tuple(sorted(new_stick)), tuple(sorted(new_slide)), tuple(sorted(new_edge)))
    return mode, v, impact


def _impact_fast(kernel, system: ContactSystem, Mf: Factorization, t: float, q: np.ndarray, v: np.ndarray,
                 before: Mode, memory: Memory, touching, gap_tol, settled) -> tuple[np.ndarray, dict] | None:
    """:func:`resolve`'s result (velocity after, impact record) on the compiled kernels when the event is an
    impact after which every contact is open (frictionless, or with friction on fixed surfaces), else None:
    then nothing of ``memory`` has changed and :func:`resolve`'s full path runs (it is this path's
    specification, which the kernels mirror step for step: _resolve.pyx's ``ImpactPath``).

    Not this path's: a candidate on a moving surface, a creeping approach, no approach, a contact closed
    after the impact or lifted without impacting (micro-lifts, the transition LCP), a touching contact pushed
    into approach (set closure), an LCP the direct kernels decline or do not solve, a non-finite state,
    arguments of other shapes than (n,) and (m,) (a gap tolerance given as one number, a list)."""
    if memory.impacts.dtype != np.int64 or memory.max_approach.dtype != np.float64:   # (written in place by the kernel)
        return None
    cs = system.contacts
    # (the kernels read q[i], q'[i], gap_tol[k] and the memory's per-contact arrays without bounds checks, and
    # write the Zeno memory in place: other shapes take the full path, which broadcasts a number or refuses)
    if not _fits(cs, q, v, memory.gap_scale, memory.rate_scale, memory.max_approach, memory.impacts, gap_tol):
        return None
    path = memory.impact_path(system, Mf, kernel)
    state, vf = np.empty((6, cs.m)), _floats(v)
    na = path.classify(_floats(q), vf, memory.gap_scale, memory.rate_scale,
                       _EMPTY if gap_tol is None else _floats(gap_tol), float(memory.gap_floor), before.closed,
                       touching, settled, state)
    if na <= 0:
        return None
    active = path.active()
    mat = path.matrices.get(active)
    if mat is None:
        key = (id(system), id(Mf), "impact", active)
        entry = _impact_parts(Mf, cs, active, memory.lcp_cache, key)[0]
        if entry[5] is None:   # (a non-finite matrix part)
            return None
        mat = kernel.Matrix(entry[0], entry[2], entry[7], na, entry[5], entry[8])
        # kept as long as the LCP cache would keep it: at most its number of entries, the oldest dropped first,
        # none it declined (larger than its byte budget: an unreduced model's M^-1 W)
        cache = memory.lcp_cache
        if cache.get(key) is entry:
            while path.matrices and len(path.matrices) >= cache.entries:
                del path.matrices[next(iter(path.matrices))]
            path.matrices[active] = mat
    x, v_new, ke = np.empty(mat.A.shape[0]), np.empty(cs.n), np.empty(2)

    def general():
        res = lemke(mat.A, x.copy(), groups=mat.groups, scales=mat.scales)
        return res.x if res.success else None

    if not path.open(mat, general, vf, state, memory.max_approach, memory.impacts, float(memory.zeno), x,
                     v_new, ke):
        return None
    memory.gap_scale, memory.rate_scale = state[0], state[1]
    memory.abs_parts(cs)
    if memory._abs[4]:   # the slip scales as observe forms them (contacts with friction)
        memory.observe_slip(cs, np.abs(q), np.abs(v))
    memory.degenerate = []
    gv = state[3].tolist()
    impact = {"t": t, "contacts": list(active), "impulse_Ns": x[:na].tolist(), "approach_m_s": [-gv[k] for k in active],
              "plastic": path.plastic(), "kinetic_before_J": float(ke[0]), "kinetic_after_J": float(ke[1])}
    return v_new, impact


def _rolling(cs, k: int, t: float, why: str) -> NsfemError:
    """The error for a contact that would stick to (roll on) a moving surface."""
    return NsfemError(f"{cs.labels[k]} would stick to the stator's moving surface at t = {t:.9g} s (rolling contact: "
                      f"{why}); the event-driven methods hold a sticking contact as a fixed slip, which a surface "
                      "sliding past at Omega r is not: run this scene with simulation.method = \"moreau\"")


def _friction_states(cs, closed, q, v, slipping, facets, memory, stopped=()):
    """Sticking contacts (zero slip rate), sliding ones with their generator (the one the stick
    limit was reached on, else the one most opposing the slip velocity) and facet candidates
    (a stick limit reached on a facet, or a slip velocity on a facet normal: a tie between two
    neighbouring generators)."""
    stick, slide, edge = [], {}, {}
    for k in closed:
        if cs.r[k] == 0:
            continue
        vT = cs.slip_rate(k, q, v)
        tolv = max(ZERO * memory.slip_scale[k], float(_tol(cs.JS[k], v).max()))
        if cs.moving[k]:
            tolv = max(tolv, float(_tol(cs.JSq[k], q, cs.wS[k]).max()))
        still = k in stopped or bool(np.all(np.abs(vT) <= tolv))
        if k in slipping:
            slide[k] = slipping[k]
        elif k in facets and (facets[k][1] == "slip" or not still):
            # a stick limit reached on a facet, or a slip velocity turning onto a facet normal
            # (a slip that stops there instead goes to the stick test)
            edge[k] = facets[k][0]
        elif still:
            stick.append(k)
        else:
            B = cs.generators(k)
            p = B.T @ vT
            i, r = int(np.argmin(p)), B.shape[1]
            if B.shape[0] == 2 and r >= 3:
                j = (i + 1) % r if p[(i + 1) % r] <= p[(i - 1) % r] else (i - 1) % r
                if p[j] - p[i] <= 4.0 * tolv:
                    edge[k] = i if j == (i + 1) % r else j
                    continue
            slide[k] = i
    return stick, slide, edge


def _facet_contacts(cs, edge: dict):
    """The contact set of LCP (29) with facet candidates: on facet f the friction force is
    mu lam_N (cos(pi/r) n_f + s t_f); the fixed part goes to the normal column (``extra``),
    s is a 1-D friction unknown along t_f with coefficient mu sin(pi/r)."""
    if not edge:
        return cs, None
    JS, mu, r, JSq, wS = list(cs.JS), cs.mu.copy(), cs.r.copy(), list(cs.JSq), list(cs.wS)
    extra = {}
    for k, f in edge.items():
        n_f, t_f, c, sn = cs.facet(k, f)
        JS[k] = (cs.JS[k] @ t_f)[:, None]
        JSq[k], wS[k] = (cs.JSq[k] @ t_f)[:, None], np.array([cs.wS[k] @ t_f])
        mu[k], r[k] = cs.mu[k] * sn, 2
        extra[k] = cs.mu[k] * c * (cs.JS[k] @ n_f)
    return replace(cs, JS=tuple(JS), mu=mu, r=r, JSq=tuple(JSq), wS=tuple(wS)), extra


def _settle(system: ContactSystem, Mf: Factorization, t: float, v: np.ndarray, hold, settled, impact,
            plastic: bool = False) -> tuple[np.ndarray, dict]:
    """Project v onto g' = 0 on ``hold`` (the nearest velocity in the kinetic metric) and record
    it in the event's impact record (created if there is none; ``settled`` are the contacts it
    settles, the kinetic energy it removes counts as impact loss)."""
    cs = system.contacts
    J = cs.JN[:, hold]
    Y = Mf.solve(J)
    P = np.linalg.lstsq(J.T @ Y, -(J.T @ v), rcond=1e-12)[0]
    v_new = v + Y @ P
    ke = 0.5 * float(v @ system.M @ v), 0.5 * float(v_new @ system.M @ v_new)
    if impact is None:
        gv = J.T @ v
        impact = {"t": t, "contacts": [int(k) for k in hold], "impulse_Ns": P.tolist(),
                  "approach_m_s": [float(-x) for x in gv], "plastic": [int(k) for k in settled] if plastic else [],
                  "kinetic_before_J": ke[0], "kinetic_after_J": ke[1]}
    else:
        impact["kinetic_after_J"] = ke[1]
    impact["settled"] = sorted(set(impact.get("settled", [])) | {int(k) for k in settled})
    return v_new, impact


def hold_degenerate(mode: Mode, phase_of, memory: Memory, cs, v: np.ndarray) -> Mode:
    """Close the degenerate contacts whose gap would go negative at once (step 4 above).

    ``phase_of(mode)`` builds the phase of a configuration at the event; the gap's
    derivatives there are H A_aug^j xi for j = 1..4, judged against the size of their terms.
    """
    deg = [k for k in memory.degenerate if k not in mode.closed]
    if not deg:
        return mode
    phase = phase_of(mode)
    xi = phase.xi(phase.t0)
    Pq = phase.q_map()
    q = Pq @ xi
    const = 2 * phase.config.r
    hold = []
    for k in deg:
        row = cs.JN[:, k] @ Pq
        row[const] += cs.jN[k]
        # g, g' (candidate test) and g'' (the LCP) vanish here: judge the 3rd and 4th derivatives,
        # never the sign of round-off in g' or g''
        A, Aa = phase.A_aug, np.abs(phase.A_aug)
        a_row, a_abs = row @ A @ A, np.abs(row) @ Aa @ Aa
        d, size = 0.0, 0.0
        for _ in range(2):
            a_row, a_abs = a_row @ A, a_abs @ Aa
            d, size = float(a_row @ xi), float(a_abs @ np.abs(xi))
            if abs(d) > 1e-9 * size:
                break
        if d < -1e-9 * size:
            hold.append(k)
    if not hold:
        return mode
    stick = list(mode.stick)
    slide = list(mode.slide)
    for k in hold:
        if cs.r[k] == 0:
            continue
        vT = cs.slip_rate(k, q, v)
        if np.all(np.abs(vT) <= ZERO * max(memory.slip_scale[k], 1e-300)):
            if cs.moving[k]:   # its direction would be round-off's
                raise _rolling(cs, k, phase.t0, "a contact held closed at zero slip velocity")
            stick.append(k)
        else:
            slide.append((k, int(np.argmin(cs.generators(k).T @ vT))))
    return replace(mode, closed=tuple(sorted(set(mode.closed) | set(hold))), stick=tuple(sorted(stick)),
                   slide=tuple(sorted(slide)))
