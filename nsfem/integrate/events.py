"""Event functions of a configuration and their roots (paper section 4).

Every event function is a linear map of the phase's augmented state, h(t) = H xi(t), valid
while h >= 0:

- ``close``: the gap g of an open contact,
- ``release``: the normal force lam_N of a closed contact,
- ``slip``: the stick limit of a sticking contact, one row per facet of its friction
  polygon, mu lam_N cos(pi / r) - n_f . lam_T (r = 2: mu lam_N -+ lam_T),
- ``turn``: for a contact sliding with its friction force along generator e_i, the slip
  velocity v_T (with a moving surface's part, affine in xi) must keep e_i the most opposing generator: (e_j - e_i) . v_T >= 0 for its
  neighbours j (r = 2: -e_i . v_T >= 0, i.e. the slip stops or reverses); for a contact
  sliding with its force on facet f (``edge``), the slip along -n_f: -n_f . v_T >= 0,
- ``vertex``: for a contact sliding on facet f, the force's position s on the facet must
  stay inside it: mu lam_N sin(pi / r) -+ s >= 0,
- ``ring_engage``, ``ring_release``, ``ring_exit``, ``ring_turn``: an elastic ring's
  (:mod:`.rings`).

Roots are found without missing any: h and h' = H A_aug xi are sampled at a step of at most
1/8 of the configuration's fastest period (:meth:`Phase.max_step`); a sign change of h is a
crossing, and a sign change of h' from - to + with h >= 0 at both samples is a dip whose
minimum (root of h') is checked; an interval where h' may change sign twice (no - to + turn at
the samples, yet the Hermite cubic through them, less its error bound, reaches below the band) is
subdivided and scanned again, and so are a dip interval whose cubic is not certainly convex (it may
hold two minima) and a crossing interval unless the row certainly stays above -tol before the root
the refinement found (three roots: it may return the last): the row decreasing up to the root (the
cubic's slope with its error bound, Birkhoff and Priver's sqrt(3) / 216 dt^3 max|h^(4)|, below
zero) and above -tol before that. The cubic's minimum is exact (its ends and the roots of its
derivative). Where the phase's derivative bound is too crude to screen (the matrix-exponential
path), a local one is formed from the state at each sample (A_aug balanced, Taylor terms and a
remainder). Roots are refined to round-off by Newton's method kept inside the sign change's bracket,
from the Hermite cubic's root, on the whole row read from the state; after 3 subdivisions (4096 times finer than the step) the refined root
is taken as it is. Terms that no row's band can notice (a quarter of it over the horizon) do not
set the step; a decaying term counts at its size where the search has come (its bound over the rest
of the horizon), so the search re-plans once the fastest term it follows has decayed into that quarter
(an overdamped stiff mode after an impact then stops setting the step); once every row is armed, a coarse pass (:class:`_Coarse`) leaves out the modes each
row barely sees (1e-3 of its terms) and skips the stretches where the rest stays above the band
by more than their bound: a stiff mode then sets the step only near a root. tests/test_event_search.py
checks the search against a dense brute-force scan of random phases. A dip
that just touches zero (within the row's tolerance) is a ``graze``: it is reported, and the
transition LCP, not an impact, decides what happens.

A row that starts inside its zero band (a gap just after an impact, a force just after a
closure) is armed at 0 once it leaves the band upwards, at a sample or at a maximum between
samples (a rebound can be much shorter than the sampling step). If it leaves the band
downwards without ever rising above it, the root is placed at -tol and flagged ``in_band``:
for a gap this is a rebound below the gap's resolution, and the impact that follows is
plastic (the impact sequence has accumulated).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import core
from .closed_form import divided_exp_bound, power
from .configuration import Mode, Phase
from .rings import ring_rows

#: relative size (to the terms that make h) below which an event function counts as zero
ZERO = 1e-11
#: samples evaluated at once: FIRST_CHUNK intervals first, 4 times more each time after, up to CHUNK
#: (most events of an impact sequence lie within the first sampling interval: 256 samples would
#: cost more than the event's refinement)
FIRST_CHUNK, CHUNK = 4, 256


@dataclass
class Rows:
    """Event rows H (k x dim) of a phase, with their kind, contact and detail: the polygon
    facet of a ``slip`` or ``turn`` row (None on a 1-D tangent), the generator a ``vertex``
    row's force reaches."""

    H: np.ndarray
    kinds: list
    contacts: list
    detail: list | None = None
    #: H A_aug when formed with H (:func:`event_rows`); None: the search forms it
    Hd: np.ndarray | None = None
    #: per row, sum |H[:, :2r]| (the weights of :func:`round_off`); None: the search forms them
    weights: np.ndarray | None = None
    #: (H; H A_aug)[:, :2r] V, V the configuration's modes (without rigid coordinates), when formed once
    #: per (configuration, mode): the rows' images of a phase's terms are these times its amplitudes
    HV: np.ndarray | None = None

    @property
    def size(self) -> int:
        return len(self.kinds)


#: the rows' coefficients are read off identity maps of this size at most (an unreduced model's would
#: take n^2 memory: its rows are built per phase, as their products cost more than the set-up anyway)
ROWS_PLAN_MAX = 1024


def event_rows(phase: Phase, mode: Mode) -> Rows:
    """The event rows of a phase of configuration ``mode``, with H A_aug. Every row is a linear map of
    the phase's q, q' and force maps plus a constant, and only their constant column (q_p, the constant
    load) changes from phase to phase: the rest of H and H A_aug is formed once per (configuration,
    mode) (:class:`_RowsPlan`; elastic rings' rows, and those of a model of more than ROWS_PLAN_MAX / 2
    coordinates, are formed per phase)."""
    cfg = phase.config
    if cfg.system.rings or 2 * cfg.system.n + cfg.W.shape[1] >= ROWS_PLAN_MAX:
        rows = _event_rows(phase, mode)
        rows.Hd = rows.H @ phase.A_aug
        return rows
    plans = cfg.__dict__.setdefault("_rows_plans", {})
    plan = plans.get(mode)
    if plan is None or plan.system is not cfg.system:
        # (a configuration shared by systems of other contact geometry, a round ring's turned facets: its
        # open gaps' rows are those of the system it runs with)
        plan = plans[mode] = _RowsPlan(phase, mode)
    return plan.rows(phase)


class _RowsPlan:
    """The event rows of a (configuration, mode) as H = R_q Pq + R_v Pv + R_f Pf + K e_c (e_c the constant
    component of xi), with R and K read off the rows built on identity maps; H and H A_aug but their
    constant column formed once. A phase adds R_q q_p + R_f (its constant load's forces) + K to H's
    constant column and H[:, :2r] B f0 to H A_aug's (the constant component has no derivative)."""

    def __init__(self, phase: Phase, mode: Mode):
        cfg = phase.config
        self.system = cfg.system   # whose contact geometry the rows are (event_rows checks it)
        n, nf = cfg.system.n, cfg.W.shape[1]
        ident = _event_rows(_Basis(cfg, n, nf), mode)
        self.kinds, self.contacts, self.detail = ident.kinds, ident.contacts, ident.detail
        R = ident.H
        self.Rq, self.Rv, self.Rf, self.K = R[:, :n], R[:, n:2 * n], R[:, 2 * n:2 * n + nf], R[:, -1]
        self.c = c = 2 * cfg.r
        Pq, Pv, Pf = phase.q_map().copy(), phase.v_map(), phase.force_map().copy()
        Pq[:, c] = 0.0
        Pf[:, c] = 0.0
        self.H = self.Rq @ Pq + self.Rv @ Pv + self.Rf @ Pf
        self.Hd = self.H @ cfg.A_aug_base
        # (H and Hd but their constant column are the configuration's: so are the round-off weights and,
        # on the modal path without rigid coordinates, the rows' images of the modes)
        self.weights = np.abs(self.H[:, :c]).sum(axis=1)
        self.HV = None
        if cfg.plan is not None and cfg.k == 0:
            self.HV = np.vstack([self.H, self.Hd])[:, :c] @ cfg.plan.V

    def rows(self, phase: Phase) -> Rows:
        c = self.c
        H, Hd = self.H.copy(), self.Hd.copy()
        H[:, c] = self.Rq @ phase.qp + self.Rf @ phase.constant_forces() + self.K
        Hd[:, c] = H[:, :c] @ phase.A_aug[:c, c]
        return Rows(H, self.kinds, self.contacts, self.detail, Hd, self.weights, self.HV)


class _Basis:
    """A stand-in phase of configuration ``cfg`` whose q, q' and force maps are identity blocks (columns: q,
    q', lam, then the constant component): the rows built on it are their own coefficients."""

    def __init__(self, cfg, n: int, nf: int):
        eye = np.eye(2 * n + nf + 1)
        self.config, self.dim, self.const = cfg, 2 * n + nf + 1, 2 * n + nf
        self._maps = eye[:n], eye[n:2 * n], eye[2 * n:2 * n + nf]

    def q_map(self):
        return self._maps[0]

    def v_map(self):
        return self._maps[1]

    def force_map(self):
        return self._maps[2]


def _event_rows(phase, mode: Mode) -> Rows:
    """The rows of a phase (or of a :class:`_Basis`) built from its maps."""
    cfg = phase.config
    cs = cfg.system.contacts
    Pq, Pv, Pf = phase.q_map(), phase.v_map(), phase.force_map()
    const = getattr(phase, "const", 2 * cfg.r)  # index of the constant component of xi
    H, kinds, contacts, detail = [], [], [], []

    def add(row, kind, k, det=None):
        H.append(row)
        kinds.append(kind)
        contacts.append(k)
        detail.append(det)

    closed = set(mode.closed)
    for k in range(cs.m):
        if k not in closed:
            row = cs.JN[:, k] @ Pq
            row[const] += cs.jN[k]
            add(row, "close", k)
    index = {(kind, k, j): i for i, (kind, k, j) in enumerate(cfg.rows)}
    for k in mode.closed:
        add(Pf[index[("normal", k, 0)]], "release", k)
    for k in mode.stick:
        lamN = Pf[index[("normal", k, 0)]]
        d, r = cs.JS[k].shape[1], int(cs.r[k])
        lamT = np.array([Pf[index[("tangent", k, j)]] for j in range(d)])
        if d == 1:
            facets, bound = np.array([[1.0], [-1.0]]), 1.0
        else:
            a = (2 * np.arange(r) + 1) * math.pi / r
            facets, bound = np.column_stack([np.cos(a), np.sin(a)]), math.cos(math.pi / r)
        for j, nf in enumerate(facets):
            add(cs.mu[k] * bound * lamN - nf @ lamT, "slip", k, j if d == 2 and r >= 3 else None)
    for k, i in mode.slide:
        B = cs.generators(k)
        vT = cs.slip_rate_rows(k, Pq, Pv, const)   # a moving surface's part too (eq. 27)
        r = B.shape[1]
        neigh = {(i + 1) % r, (i - 1) % r} if B.shape[0] == 2 else {(i + r // 2) % r}
        for j in sorted(neigh):
            facet = (i if j == (i + 1) % r else j) if B.shape[0] == 2 and r >= 3 else None
            add((B[:, j] - B[:, i]) @ vT, "turn", k, facet)
    for k, i in mode.edge:
        lamN, s_f = Pf[index[("normal", k, 0)]], Pf[index[("tangent", k, 0)]]
        n_f, _, _, sn = cs.facet(k, i)
        add(cs.mu[k] * sn * lamN - s_f, "vertex", k, (i + 1) % int(cs.r[k]))
        add(cs.mu[k] * sn * lamN + s_f, "vertex", k, i)
        add(-(n_f @ cs.slip_rate_rows(k, Pq, Pv, const)), "turn", k, None)  # the slip along -n_f stops
    ring_rows(phase, mode, cfg.system.rings, cs.m, add)
    return Rows(np.array(H).reshape(len(kinds), phase.dim), kinds, contacts, detail)


@dataclass
class Event:
    t: float
    rows: list          # indices of the rows with a root at t
    graze: list         # per row: True for a tangential touch (no crossing)
    tol: np.ndarray | None = None   # per row: the size below which it counts as zero
    #: per row: True when it fired without having left its zero band since the phase began
    #: (a gap that re-closes after a rebound too small to resolve: the impacts have accumulated)
    in_band: list | None = None


def first_event(phase: Phase, rows: Rows, t_start: float, t_stop: float, report=None) -> Event | None:
    """The earliest root of any row in (t_start, t_stop], or None. ``report(t)`` (optional) is
    told how far the search has come after each chunk of samples (progress of long phases).

    The set-up (:func:`band_tolerance`, :func:`modal_images`, the plans) and the loop below run as one
    compiled call where the compiled event core is built and the phase is on the modal path
    (:func:`_compiled_search`); this code is its reference."""
    if rows.size == 0:
        return None
    H = rows.H
    Hd = H @ phase.A_aug if rows.Hd is None else rows.Hd
    if phase.config.fastest_rate() == 0.0 and phase.w == 0.0:
        return _polynomial_event(phase, rows, t_start, t_stop)
    armed = thr = None
    phase.search_samples = 0
    search = core.compiled("search")
    if search is not None and phase._modal is not None:
        # the set-up and the loop below as one compiled call on the modal path (:func:`_compiled_search`);
        # it hands the search back to this loop where a plan's bound is too crude to screen
        found = _compiled_search(search, phase, rows, t_start, t_stop, report)
        if not isinstance(found, _Handover):
            return found
        tol, t_start, armed, thr = found
    else:
        tol = band_tolerance(phase, H, t_start, t_stop, rows.weights)
    # the search follows the rows without the fastest terms whose sum stays below a quarter of each
    # row's band over the horizon (round-off amplitudes of stiff modes, modes a row does not see, modes
    # that have decayed): they no longer set the step. A row then crosses -tol no earlier than its
    # search version crosses -(tol - e), e the left-out terms' bound: the search uses that band
    HH, budget = np.vstack([H, Hd]), np.concatenate([tol / 4.0, np.full(H.shape[0], np.inf)])
    images = modal_images(phase, rows)
    k = rows.size

    def plan_from(t):
        """The search's rows, band, step and interpolation bound from t on (the left-out terms bounded
        on [t, t_stop]: a decaying one by its size at t)."""
        plan = phase.search_plan(HH, budget, t_stop - phase.t0, t - phase.t0, images=images)
        band = tol - plan.e[:k]
        step = phase.max_step(t_stop - phase.t0, plan.rate)
        # certified dip screening: |h - Hermite cubic| <= dt^4 / 384 * max |4th derivative|
        return plan, band, step, plan.bound(4)[:k] * power(step, 4) / 384.0

    plan, band, h_step, bound4 = plan_from(t_start)
    rows_at = plan.rows
    # (a renewal that rounds to where the plan starts is tried again a step later: the search advances)
    renew_at = max(phase.t0 + plan.renew, t_start + h_step)
    coarse, tried = None, False
    t_a = t_start
    chunk = FIRST_CHUNK
    while t_a < t_stop:
        if t_a >= renew_at:
            # the fastest term kept has decayed into its budget: it no longer sets the step (an
            # overdamped stiff mode after an impact), nor the coarse pass's
            plan, band, h_step, bound4 = plan_from(t_a)
            rows_at = plan.rows
            renew_at = max(phase.t0 + plan.renew, t_a + h_step)
            coarse, tried = None, False
        t_b = min(t_stop, renew_at)
        if not tried and armed is not None and armed.all():
            # formed once a first chunk has found nothing (most phases of an impact burst end in it)
            coarse, tried = _Coarse.of(phase, H, Hd, band, plan.rate, t_a, t_stop, images), True
        if coarse is not None:
            # every row armed at 0: skip what the coarse pass certifies, search the rest finely
            t_skip, t_c = coarse.unclear(t_a)
            t_b = min(t_b, t_c)
            if t_skip > t_a:
                t_a = phase.searched_until = t_skip
                chunk = FIRST_CHUNK
                if report is not None:
                    report(t_a)
                if t_a >= t_stop:
                    break
                if t_a >= t_b:
                    continue
        n = max(1, min(chunk, math.ceil((t_b - t_a) / h_step)))
        chunk = min(CHUNK, 4 * chunk)
        ts = np.linspace(t_a, min(t_b, t_a + n * h_step), n + 1)
        hh = rows_at(ts)
        phase.search_samples += ts.size
        h, hd = hh[: rows.size], hh[rows.size:]
        if armed is None:
            # a row that starts inside its zero band is armed once it has left it upwards
            armed = h[:, 0] > band
            # unarmed rows fire by going down by the band from where they start (a row can start
            # below -tol: a gap located with a previous phase's larger band)
            thr = np.where(armed, 0.0, np.minimum(-band, h[:, 0] - band))
        found = []
        maybe, (cross, turn, near), ok = _screened(ts, h - thr[:, None], hd, band, bound4)
        maybe |= ~armed
        # rows in the order of their first sample below threshold (a cheap lower bound of where
        # their root lies); a row whose first candidate interval starts after the earliest root
        # refined so far cannot be the first event and is not refined (same result, fewer roots)
        below = (h - thr[:, None]) < -band[:, None]
        first = np.where(below.any(axis=1), np.argmax(below, axis=1), h.shape[1])
        limit = math.inf
        for i in np.argsort(first, kind="stable"):
            if not maybe[i]:
                continue
            hi, hdi = h[i], hd[i]
            row = _Row(phase, H[i], Hd[i])
            res = None
            if not armed[i]:
                # the row starts in its zero band: it fires from there only by leaving it downwards
                # (root at -tol, flagged: it never rose above the band); once it has left the band
                # upwards (a sample or a maximum between samples above tol) it is armed at 0
                arm = _arm(row, ts, hi, hdi, band[i], bound4[i])
                if arm is None:
                    res = _scan(row, ts, hi, hdi, thr[i], band[i], bound4[i], limit)
                else:
                    # only a descent before the arming time is the row's own: after it the row is
                    # armed at 0 and scanned from there (its first samples end at the arming point)
                    (ts1, h1, hd1), after = _cut(row, ts, hi, hdi, *arm)
                    res = _scan(row, ts1, h1, hd1, thr[i], band[i], _shorter(bound4[i], ts1, ts[1] - ts[0]), limit)
                if (res is not None and arm is not None and res[0] <= arm[0]
                        and (res[0] <= ts[0] or row.at(res[0])[1] > 0.0)):
                    # a "crossing" at the phase's start, or where the row is rising, is the
                    # round-off of evaluating the row near its start (a gap lifted at 1e-4 m/s or
                    # opening from rest, evaluated to 1e-18 m next to a band of 1e-20 m): not a
                    # descent by tol; the row arms where it rises above its band
                    res = None
                if res is not None and (arm is None or res[0] <= arm[0]):
                    res = (res[0], res[1], True)
                elif arm is not None:
                    res = None
                    armed[i], thr[i] = True, 0.0
                    ts2, h2, hd2 = after
                    res = _scan(row, ts2, h2, hd2, 0.0, band[i], _shorter(bound4[i], ts2, ts[1] - ts[0]), limit)
            else:
                res = _scan(row, ts, hi, hdi, thr[i], band[i], bound4[i], limit,
                            screen=(cross[i], turn[i], near[i]) if ok[i] else None)
            if res is not None:
                found.append((res[0], int(i), res[1], len(res) > 2))
                limit = min(limit, res[0] + 1e-12 * max(1.0, abs(res[0])))
        if found:
            t_e = min(f[0] for f in found)
            close = sorted((f for f in found if f[0] <= t_e + 1e-12 * max(1.0, abs(t_e))), key=lambda f: f[1])
            return Event(t_e, [f[1] for f in close], [f[2] for f in close], tol, [f[3] for f in close])
        t_a = ts[-1]
        phase.searched_until = t_a  # no event before this time (an interrupted run keeps it)
        if report is not None:
            report(t_a)
    return None


def band_tolerance(phase: Phase, H: np.ndarray, t_start: float, t_stop: float,
                   weights: np.ndarray | None = None) -> np.ndarray:
    """Per row of H, the size below which it counts as zero from t_start on: ZERO times the largest sum of
    the terms that make it, |H| |xi(t)|, at 33 times over the next 4 periods of the fastest mode (up to
    t_stop if sooner: t_end matters only within 4 periods of it), and never below the round-off of
    evaluating the row from the state (:func:`round_off`, ``weights`` its row weights when formed): a
    row starting at ~0 (a gap of 1e-19 m read to +-1e-18 m) must not fire by that noise."""
    step = phase.max_step(math.inf)
    window = min(step, t_stop - t_start) if math.isfinite(step) else t_stop - t_start
    xis = phase.xi_on_grid(t_start, window / 32.0, 33)
    scale = np.max(np.abs(H) @ np.abs(xis), axis=1) + 1e-300
    return np.maximum(ZERO * scale, round_off(H, xis, 2 * phase.config.r, weights))


def modal_images(phase: Phase, rows: Rows) -> np.ndarray | None:
    """(H; H A_aug)[:, :2r] U, the rows' coefficients of the phase's exponential terms (rows.size * 2 x
    terms; None off the modal path): with the rows' images of the modes formed once per configuration
    (rows.HV) and the phase's amplitudes (c, g), U = V [diag(c), g^T] gives them as HV diag(c) and HV g^T
    (O(rows m) per phase instead of O(rows r m))."""
    if phase._modal is None:
        return None
    if rows.HV is not None and phase.amplitudes is not None:
        c, g = phase.amplitudes
        return np.hstack([rows.HV * c, rows.HV @ g.T])
    r2 = 2 * phase.config.r
    Hd = rows.H @ phase.A_aug if rows.Hd is None else rows.Hd
    return np.vstack([rows.H, Hd])[:, :r2] @ phase._modal.U


def _compilable(phase: Phase, rows_at, band: np.ndarray, bound4: np.ndarray) -> bool:
    """Whether the compiled search (nsfem/integrate/core/_search.pyx) can run a plan: the modal path
    (divided differences included), every row's bound fine enough to screen (no local bound). (The
    compiled call checks the same of its own plans, ``Search.compilable``.)"""
    return (phase._modal is not None and getattr(rows_at, "terms", None) is not None
            and bool(np.all(bound4 <= band * float(SUBDIVIDE) ** (4 * DEPTH))))


class _Handover(tuple):
    """What the compiled search hands back where a plan's bound is too crude to screen: (tol, t, armed,
    thr), the search to go on from t in Python (armed, thr: the rows' arming so far, or None)."""


def _terms(mot) -> tuple:
    """A closed form's terms as the compiled search reads them: (exponents, nodes of the divided
    differences (K x 3, unused nodes 0), their number of nodes (2 or 3), coefficients (rows x
    (exponents + K)))."""
    nodes = [np.vstack([n, np.zeros((3 - n.shape[0], n.shape[1]))]) for n, _ in mot.groups]
    gnodes = np.concatenate(nodes, axis=1).T if nodes else np.zeros((0, 3))
    gm = np.concatenate([np.full(n.shape[1], n.shape[0]) for n, _ in mot.groups]) if nodes else np.zeros(0)
    C = np.hstack([mot.U] + [D for _, D in mot.groups]) if nodes else mot.U
    return (np.ascontiguousarray(mot.nu, dtype=complex), np.ascontiguousarray(gnodes, dtype=complex),
            np.ascontiguousarray(gm, dtype=np.intc), np.ascontiguousarray(C, dtype=complex))


def _compiled_search(search, phase: Phase, rows: Rows, t_start: float, t_stop: float,
                     report) -> "Event | None | _Handover":
    """:func:`first_event` on the modal path as one compiled call (``search.Search``): its set-up (the band
    from the state at 33 times, :func:`band_tolerance`; the plans of :meth:`Phase.search_plan` from the rows'
    images of the phase's terms, :func:`modal_images`, renewed where the fastest kept term has decayed) and
    its loop (the same chunks, screens, scans, arming, coarse pass (:meth:`_Coarse.of`) and roots) over
    [t_start, t_stop]; ``report`` and ``phase.searched_until`` follow its progress. A :class:`_Handover`
    where a plan cannot be screened without the local bound."""
    mot, cfg, k = phase._modal, phase.config, rows.size
    H = np.ascontiguousarray(rows.H, dtype=float)
    Hd = np.ascontiguousarray(H @ phase.A_aug if rows.Hd is None else rows.Hd, dtype=float)
    r2 = 2 * cfg.r
    nu, gnodes, gm, U = _terms(mot)
    horizon = t_stop - phase.t0
    gb, node_rate = _NO_GROUPS, 0.0
    if rows.HV is not None and phase.amplitudes is not None:
        images = (rows.HV, *phase.amplitudes)   # (formed in the call as modal_images forms them)
    else:
        images = modal_images(phase, rows)
        if mot.groups:   # the divided differences' images and bounds of order 4 and 0 (independent of t)
            HH = np.vstack([H, Hd])[:, :r2]
            images = np.hstack([images] + [HH @ D for _, D in mot.groups])
            gb = np.array([np.concatenate([divided_exp_bound(nodes, order, horizon) for nodes, _ in mot.groups])
                           for order in (4, 0)])
            node_rate = max(float(np.max(np.abs(nodes), initial=0.0)) for nodes, _ in mot.groups)
        images = np.ascontiguousarray(images, dtype=complex)
    weights = np.abs(H[:, :r2]).sum(axis=1) if rows.weights is None else rows.weights
    _, order, steady = cfg.term_order(mot.nu)
    tol, band = np.empty(k), np.empty(k)

    def progress(t):
        phase.searched_until = t
        if report is not None:
            report(t)

    run = search.Search(nu, gnodes, gm, U, H, Hd, phase.A_aug, phase.t0, float(phase.w), images,
                        _order_c(cfg, order), bool(steady), weights, gb, node_rate, cfg.fastest_rate(),
                        float(t_start), float(t_stop), tol, band)
    carry = [None, None]
    try:
        found = run.run(progress, carry)
    finally:
        phase.search_samples += run.sampled   # (the fine passes' samples, as the loop below counts them)
    if isinstance(found, float):
        armed = None if carry[0] is None else np.array(carry[0], dtype=bool)
        thr = None if carry[1] is None else np.array(carry[1], dtype=float)
        return _Handover((tol, found, armed, thr))
    if found is None:
        return None
    t_e, idx, graze, in_band = found
    return Event(t_e, idx, graze, tol, in_band)


_NO_GROUPS = np.zeros((2, 0))


def _order_c(cfg, order: np.ndarray) -> np.ndarray:
    """The configuration's term order (Configuration.term_order) as C ints, formed once per order."""
    cached = cfg.__dict__.get("_order_c")
    if cached is None or cached[0] is not order:
        cached = cfg._order_c = (order, np.ascontiguousarray(order, dtype=np.intc))
    return cached[1]


#: the coarse pass leaves out the fastest terms up to COARSE of each row's size; it is used when that
#: slows its sampling COARSE_GAIN times or more than the fine search's
COARSE, COARSE_GAIN = 1e-3, 4.0


class _Coarse:
    """Certified skipping for rows armed at 0 (paper's rows h = H xi, all of them at once).

    The slow part s of each row (the fastest terms left out up to COARSE of its size, their sum e
    over the horizon: |h - s| <= e) is sampled at the step of the slowest rate that leaves; on an
    interval where s, by its Hermite cubic less the interpolation bound, stays above band + e, the
    row stays above its band: no crossing, no dip, nothing for the fine search. A stiff mode a gap
    barely sees (an unreduced shaft's 500 kHz modes, 1e-4 of the gap's swing) then sets the step
    only where some gap comes within that much of zero."""

    def __init__(self, rows_at, margin, b4, step, t_start, t_stop, k):
        self.rows_at, self.margin, self.b4, self.step = rows_at, margin, b4, step
        self.t_start, self.t_stop, self.k = t_start, t_stop, k
        self.ts = np.zeros(0)
        self.clear = np.zeros(0, dtype=bool)

    @classmethod
    def of(cls, phase, H, Hd, band, rate, t_start, t_stop, images=None) -> "_Coarse | None":
        """The coarse pass of a search from t_start, or None when it would not sample COARSE_GAIN times
        slower (``images``: :func:`modal_images` of the rows, when formed)."""
        horizon = t_stop - phase.t0   # the terms' bounds hold from the phase's start
        k = H.shape[0]
        # a row's size: the sum of its modal terms' amplitudes (a gap's, not the layers' it is the
        # difference of) and its constant
        size = phase.derivative_bound(H, 0, horizon, None if images is None else images[:k]) + \
            np.abs(H[:, 2 * phase.config.r])
        budget = np.concatenate([COARSE * size, np.full(k, np.inf)])
        # (the terms bounded from t_start on: a decaying one at its size there)
        plan = phase.search_plan(np.vstack([H, Hd]), budget, horizon, t_start - phase.t0, images=images)
        step = phase.max_step(horizon, plan.rate)
        if step < COARSE_GAIN * phase.max_step(horizon, rate) or plan.bound is None or step * 4.0 > t_stop - t_start:
            return None
        b4 = plan.bound(4)[:k] * power(step, 4) / 384.0
        return cls(plan.rows, band + plan.e[:k], b4, step, t_start, t_stop, k)

    def _extend(self) -> None:
        """Sample the next CHUNK coarse intervals and judge them."""
        t0 = self.ts[-1] if self.ts.size else self.t_start
        n = max(1, min(CHUNK, math.ceil((self.t_stop - t0) / self.step)))
        ts = np.linspace(t0, min(self.t_stop, t0 + n * self.step), n + 1)
        ss = self.rows_at(ts)
        s, sd = ss[: self.k] - self.margin[:, None], ss[self.k:]
        dt = np.diff(ts)
        # the cubic's Hermite weights of the slopes are at most 4/27: a cheap lower bound first
        lo = np.minimum(s[:, :-1], s[:, 1:]) - 4.0 / 27.0 * dt * (np.abs(sd[:, :-1]) + np.abs(sd[:, 1:]))
        lo -= self.b4[:, None]
        i, j = np.nonzero(lo <= 0.0)
        if i.size:
            lo[i, j] = _hermite_min(s[i, j], s[i, j + 1], sd[i, j], sd[i, j + 1], dt[j]) - self.b4[i]
        clear = np.all(lo > 0.0, axis=0)
        self.ts = ts if not self.ts.size else np.concatenate([self.ts, ts[1:]])
        self.clear = np.concatenate([self.clear, clear])

    def unclear(self, t: float) -> tuple[float, float]:
        """(a, b): the first stretch at or after t not certified clear, from a (t itself when t lies in
        one) to b (the end of its run of coarse intervals); a = t_stop when all is clear."""
        j = max(int(np.searchsorted(self.ts, t, side="right")) - 1, 0)
        while True:
            while j >= self.clear.size:
                if self.ts.size and self.ts[-1] >= self.t_stop:
                    return self.t_stop, self.t_stop
                self._extend()
            if not self.clear[j]:
                break
            j += 1
        a = max(t, float(self.ts[j]))
        while True:
            if j >= self.clear.size:
                if self.ts[-1] >= self.t_stop:
                    return a, self.t_stop
                self._extend()
                continue
            if self.clear[j]:
                return a, float(self.ts[j])
            j += 1


def _screened(ts, f, hd, band, bound4) -> tuple[np.ndarray, tuple, np.ndarray]:
    """(maybe, screens, ok): per row, False when :func:`_scan` certainly finds no candidate interval on
    these samples (no crossing, no near dip, nothing to subdivide: all rows screened at once, as each
    scan would), True also for a row whose bound needs the local one (the matrix-exponential path, ok
    False); and the (cross, turn, near) of all rows, row i's what its scan of these samples would form
    where ok[i]."""
    dt = np.diff(ts)
    ok = bound4 <= band * float(SUBDIVIDE) ** (4 * DEPTH)   # depth 0: subdivided where the bound screens
    b4 = np.broadcast_to(bound4[:, None], (f.shape[0], dt.size))
    sub = np.broadcast_to(ok[:, None], b4.shape)
    cross, turn, near = _screen(dt, f, hd, band[:, None], b4, sub)
    return ~ok | cross.any(axis=1) | near.any(axis=1), (cross, turn, near), ok


def round_off(H: np.ndarray, xis: np.ndarray, r2: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Per row, the round-off of evaluating h = H xi from a state: a few ulps of the largest
    state component times the row's weights (sum |H[:, :r2]|, given or formed). A row can be much
    smaller than the state it is read from (the gap coordinate of a Craig-Bampton model, 1e-8 m, next
    to velocities of 1e-2 m/s): its band must not fall below what a restart from that state reproduces."""
    if r2 == 0:
        return np.zeros(H.shape[0])
    if weights is None:
        weights = np.abs(H[:, :r2]).sum(axis=1)
    return 16.0 * np.finfo(float).eps * weights * float(np.abs(xis[:r2]).max())


def _cubic(f0, f1, d0, d1, dt):
    """Coefficients c0..c3 of the Hermite cubic with end values f0, f1 and slopes d0, d1 over an
    interval of length dt, in s = (t - a) / dt: c0 + c1 s + c2 s^2 + c3 s^3."""
    m0, m1 = dt * d0, dt * d1
    df = f1 - f0
    return f0, m0, 3.0 * df - 2.0 * m0 - m1, m0 + m1 - 2.0 * df


#: coefficients of a quadratic beyond 2^+-SAFE are scaled by a power of two (exactly) first: b^2 - 4ac
#: under- or overflows beyond about 1e+-154, and the roots do not depend on the scale
SAFE = 400


def _quadratic_roots(a, b, c):
    """The two roots of a s^2 + b s + c (vectorized; nan or inf where there is none), by the
    formula without cancellation (a = 0 leaves the linear root -c / b in the second)."""
    with np.errstate(all="ignore"):
        m = np.abs(a) + np.abs(b) + np.abs(c)
        if not 2.0 ** -SAFE <= np.min(m) <= np.max(m) <= 2.0 ** SAFE:   # (rare: then per entry)
            far = (m > 0) & np.isfinite(m) & ((m < 2.0 ** -SAFE) | (m > 2.0 ** SAFE))
            k = np.where(far, -np.frexp(m)[1], 0)
            a, b, c = np.ldexp(a, k), np.ldexp(b, k), np.ldexp(c, k)
        disc = b * b - 4.0 * a * c
        q = -0.5 * (b + np.copysign(np.sqrt(np.where(disc >= 0, disc, np.nan)), b))
        return q / a, c / q


def _roots2(a: float, b: float, c: float) -> list[float]:
    """The real roots of a s^2 + b s + c for scalars (the formula without cancellation; a = 0: the
    linear root; coefficients beyond 2^+-SAFE scaled first)."""
    m = max(abs(a), abs(b), abs(c))
    if 0.0 < m < math.inf and not 2.0 ** -SAFE <= m <= 2.0 ** SAFE:
        k = -math.frexp(m)[1]
        a, b, c = math.ldexp(a, k), math.ldexp(b, k), math.ldexp(c, k)
    if a == 0.0:
        return [-c / b] if b != 0.0 else []
    disc = b * b - 4.0 * a * c
    if not disc >= 0.0:
        return []
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    return [q / a, c / q] if q != 0.0 else [0.0]


def _hermite_min(f0, f1, d0, d1, dt):
    """Minimum over each interval of the cubic with end values f0, f1 and slopes d0, d1: exact,
    at the ends or at a root of its derivative (a quadratic) inside the interval."""
    c0, c1, c2, c3 = _cubic(f0, f1, d0, d1, dt)
    out = np.minimum(f0, f1)
    for r in _quadratic_roots(3.0 * c3, 2.0 * c2, c1):
        inside = (r > 0.0) & (r < 1.0)   # (False for nan and inf)
        if inside.any():
            s = np.where(inside, r, 0.0)
            out = np.where(inside, np.minimum(out, c0 + s * (c1 + s * (c2 + s * c3))), out)
    return out


#: Birkhoff and Priver (1967): the cubic Hermite interpolant's slope is off by at most
#: sqrt(3) / 216 dt^3 max|h^(4)|, i.e. by SLOPE * bound4 in units of the interval (d/ds = dt d/dt,
#: bound4 = dt^4 / 384 max|h^(4)|); its value by 16 bound4 s^2 (1 - s)^2, its curvature by 32 bound4
SLOPE = 384.0 * math.sqrt(3.0) / 216.0


def _cubic_max(f0, f1, d0, d1, dt) -> float:
    """The maximum over the interval of the Hermite cubic with end values f0, f1 and slopes d0, d1 (floats):
    -:func:`_hermite_min` of the negated data, the same operations."""
    c0, c1, c2, c3 = _cubic(-f0, -f1, -d0, -d1, dt)
    low = min(-f0, -f1)
    for r in _roots2(3.0 * c3, 2.0 * c2, c1):
        if 0.0 < r < 1.0:
            low = min(low, c0 + r * (c1 + r * (c2 + r * c3)))
    return -low


def _cubic_argmax(c0, c1, c2, c3) -> float:
    """Where on [0, 1] the cubic c0 + c1 s + c2 s^2 + c3 s^3 is largest (an end or a root of its
    derivative)."""
    ss = [0.0, 1.0] + _roots2(3.0 * c3, 2.0 * c2, c1)
    return max((s for s in ss if 0.0 <= s <= 1.0), key=lambda s: c0 + s * (c1 + s * (c2 + s * c3)))


def _convex(f0, f1, d0, d1, dt, bound4):
    """True when the row is certainly convex on the interval (a dip's minimum is its only one):
    the cubic's second derivative, linear, less its error bound (Birkhoff and Priver:
    dt^2 / 12 max|h^(4)|, 32 bound4 in units of the interval) is positive at both ends."""
    _, _, c2, c3 = _cubic(f0, f1, d0, d1, dt)
    return min(2.0 * c2, 2.0 * c2 + 6.0 * c3) > 32.0 * bound4


def _envelope_min(f0, f1, d0, d1, dt, bound4, s_hi=1.0):
    """The lowest the row can be on [0, s_hi] of the interval (in its units): the Hermite cubic
    less its pointwise error bound 16 bound4 s^2 (1 - s)^2, a quartic p, at the ends or at a minimum
    inside. The roots of p'' (a quadratic) cut [0, s_hi] into pieces on which p' is monotone; a piece
    where p' goes from - to + holds one minimum, found by Newton's method kept inside the piece."""
    c0, c1, c2, c3 = _cubic(f0, f1, d0, d1, dt)
    e = 16.0 * bound4
    a3, a2, a1 = -4.0 * e, 3.0 * c3 + 6.0 * e, 2.0 * c2 - 2.0 * e    # p' = c1 + a1 s + a2 s^2 + a3 s^3

    def p(s):
        w = s * (1.0 - s)   # (w * w, not w ** 2: Python's pow rounds differently from C's product)
        return c0 + s * (c1 + s * (c2 + s * c3)) - e * (w * w)

    def dp(s):
        return c1 + s * (a1 + s * (a2 + s * a3))

    knots = [0.0] + sorted(r for r in _roots2(3.0 * a3, 2.0 * a2, a1) if 0.0 < r < s_hi) + [s_hi]
    low = min(p(s) for s in knots)
    for u, v in zip(knots[:-1], knots[1:]):
        fu, fv = dp(u), dp(v)
        if not (fu < 0.0 < fv):
            continue
        x = u - fu * (v - u) / (fv - fu)
        for _ in range(MAXITER):
            fx = dp(x)
            if fx == 0.0:
                break
            if fx < 0.0:
                u = x
            else:
                v = x
            d2 = a1 + x * (2.0 * a2 + 3.0 * a3 * x)
            x_new = x - fx / d2 if d2 > 0.0 else 0.5 * (u + v)
            if not u < x_new < v:
                x_new = 0.5 * (u + v)
            if abs(x_new - x) <= 4e-16 * max(1.0, abs(x)) or v - u <= 4e-16 * max(1.0, abs(v)):
                x = x_new
                break
            x = x_new
        low = min(low, p(x))
    return low


def _first_root(f0, f1, d0, d1, dt, s_r, bound4, tol):
    """True when no earlier point of the interval than s_r (a root, in units of the interval) can
    be below -tol: the row is certainly decreasing on [s_x, s_r] (the cubic's slope plus its
    error bound below zero there) and certainly above -tol on [0, s_x] (the cubic less its error
    bound). Three roots in the interval fail it."""
    c0, c1, c2, c3 = _cubic(f0, f1, d0, d1, dt)
    e1 = SLOPE * bound4
    if not c1 + e1 + s_r * (2.0 * c2 + 3.0 * c3 * s_r) < 0.0:
        return False
    s_x = max([r for r in _roots2(3.0 * c3, 2.0 * c2, c1 + e1) if 0.0 < r < s_r], default=0.0)
    # decreasing from the sample (>= -tol) to the root, or above -tol up to where it certainly is
    return s_x == 0.0 or _envelope_min(f0, f1, d0, d1, dt, bound4, s_x) >= -tol


def _cut(row: "_Row", ts, h, hd, t_arm: float, k: int):
    """The samples (times, h, h') of a row up to its arming time t_arm in [ts[k], ts[k + 1]] and from
    it on, that point in both (once in the first when it is ts[k])."""
    h_arm, hd_arm = row.at(t_arm)
    after = (np.append(t_arm, ts[k + 1:]), np.append(h_arm, h[k + 1:]), np.append(hd_arm, hd[k + 1:]))
    if t_arm <= ts[k]:
        return (ts[:k + 1], h[:k + 1], hd[:k + 1]), after
    return (np.append(ts[:k + 1], t_arm), np.append(h[:k + 1], h_arm), np.append(hd[:k + 1], hd_arm)), after


def _shorter(bound4: float, ts: np.ndarray, step: float) -> np.ndarray:
    """Per interval of ts, the interpolation bound ``bound4`` of a sampling step scaled to the
    interval's own length (it goes with dt^4): an interval cut at an arming point is much shorter."""
    return bound4 * np.minimum(np.diff(ts) / step, 1.0) ** 4


def _arm(row: "_Row", ts, h, hd, tol, bound4):
    """(t, k): the first time a row that starts in its zero band is above it (at a sample or
    at a maximum between samples ts[k], ts[k + 1]), or None.

    Between samples the Hermite cubic's maximum plus its error bound screens the intervals;
    a candidate's maximum is refined (root of h', or a fine grid when h' does not change sign).
    """
    if ts.size < 2:
        return None
    if ts.size <= ROW_SCREEN + 1:
        # a few intervals (the first chunk after an impact): the cubics' maxima in plain floats, as
        # _hermite_min forms them (NumPy's calls would cost more than the arithmetic)
        tl, hl, hdl = ts.tolist(), h.tolist(), hd.tolist()
        hmax = [_cubic_max(hl[k], hl[k + 1], hdl[k], hdl[k + 1], tl[k + 1] - tl[k]) for k in range(len(tl) - 1)]
        cand = [k for k in range(len(hmax)) if hl[k + 1] > tol or hmax[k] + bound4 > tol]
    else:
        dt = np.diff(ts)
        hmax = -_hermite_min(-h[:-1], -h[1:], -hd[:-1], -hd[1:], dt)
        cand = np.flatnonzero((h[1:] > tol) | (hmax + bound4 > tol))
    for k in cand[:64]:
        a, b = ts[k], ts[k + 1]
        if hmax[k] - bound4 > tol:
            # the cubic's maximum, less its error bound, is above the band: the row there is too
            # (read from the state to be sure); the arming time need not be the row's own maximum
            tc = a + (b - a) * _cubic_argmax(*_cubic(h[k], h[k + 1], hd[k], hd[k + 1], b - a))
            hc = row.value(tc)
            if hc > tol:
                return tc, int(k)
        tm = _root(row.slope, a, b) if hd[k] > 0 >= hd[k + 1] else None
        if tm is not None:
            hm = row.value(tm)
        else:
            # no sign change of h' at the samples, or none left when re-evaluated: h' is round-off
            # at an end (a gap lifting off from rest, h'(a) = +-1e-17, can rise 1e-9 and come back
            # within the interval: its maximum is not at an end)
            grid = np.linspace(a, b, 33)
            vals = row.samples(grid)[0]
            j = int(np.argmax(vals))
            tm, hm = float(grid[j]), float(vals[j])
        if hm > tol:
            return tm, int(k)
        if h[k + 1] > tol:
            return float(b), int(k)
    return None


class _Row:
    """Row i of a search, h = H_i xi, with h' = Hd_i xi: values at one time for root refinement
    (h'' from Hd_i A_aug: the Newton steps on h'), and samples at several."""

    def __init__(self, phase: Phase, Hi: np.ndarray, Hdi: np.ndarray):
        self.phase, self.H, self.Hd = phase, Hi, Hdi
        self._values = self._map = None   # formed at the first call (most rows are never refined)
        self._memo: dict = {}

    def _rows(self):
        # read from the state xi(t), not from the rows' own modal coefficients H U: with terms that
        # cancel (a nearly rigid mode's 1 / lam^2 coefficients, 1e5 for a row of 0.04) the two differ
        # by 1e-12 in their rounding, above a band of 4e-13; the root must be one of the state the
        # next phase starts from (its gap inside the band)
        if self._values is None:
            R = np.vstack([self.H, self.Hd, self.Hd @ self.phase.A_aug])
            self._values = lambda t: R @ self.phase.xi(t)
        return self._values

    def _eval(self, t: float) -> tuple[float, float, float]:
        """(h, h', h'') at t; the last few times are remembered (a root's bracket ends are often
        where the caller has just read the row)."""
        t = float(t)
        v = self._memo.get(t)
        if v is None:
            if len(self._memo) >= 8:
                self._memo.clear()
            v = self._memo[t] = tuple(self._rows()(t).tolist())
        return v

    def at(self, t: float) -> tuple[float, float]:
        """(h, h') at t."""
        v = self._eval(t)
        return v[0], v[1]

    def slope(self, t: float) -> tuple[float, float]:
        """(h', h'') at t."""
        v = self._eval(t)
        return v[1], v[2]

    def value(self, t: float) -> float:
        """h at t."""
        return self._eval(t)[0]

    def samples(self, ts: np.ndarray) -> np.ndarray:
        """(h, h') at the times ts (2 x len(ts))."""
        if self._map is None:
            self._map = self.phase.row_map(np.vstack([self.H, self.Hd]))
        return self._map(np.atleast_1d(np.asarray(ts, dtype=float)))


#: Newton steps at most in :func:`_root` (bisections included: each halves the bracket at least)
MAXITER = 200


def _root(at, a, b):
    """A root of f in [a, b] to round-off, ``at(t)`` = (f(t), f'(t)); None when the re-evaluated ends
    show no sign change (the samples came from a product whose round-off differs in the last bits).

    Newton's method from the root of the Hermite cubic through the ends, kept inside the bracket
    of the sign change, until a step is below xtol + rtol |t| (4e-16 max(1, |b|) + 8.9e-16 |t|, what
    Brent's method used to be asked for: Newton's error after that step is of the order of its
    square, i.e. round-off) or the bracket is that narrow. A step that does not halve the one before
    (Newton stalls: on a near-double root, or on the round-off of a slow row, 1e-19 read with a slope
    of 1e-4) is taken twice over, past the root, to close the bracket there; if that does not halve
    it either, or a step leaves the bracket, it is bisected."""
    a, b = float(a), float(b)
    fa, da = at(a)
    fb, db = at(b)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0) == (fb > 0):
        return None
    xtol = 4e-16 * max(1.0, abs(b))
    x = a + (b - a) * _cubic_root(*_cubic(fa, fb, da, db, b - a))
    prev, overshot = b - a, False
    for _ in range(MAXITER):
        fx, dx = at(x)
        if fx == 0.0:
            return x
        if (fx > 0) == (fa > 0):
            a, fa = x, fx
        else:
            b = x
        step = fx / dx if dx != 0.0 else math.inf
        tol = xtol + 8.9e-16 * abs(x)
        if abs(step) <= tol:
            return min(max(x - step, a), b)
        if b - a <= 2.0 * tol:
            return 0.5 * (a + b)
        x_new = x - step
        if a < x_new < b and abs(step) <= 0.5 * prev:
            overshot = False
        elif not overshot and a < x - 2.0 * step < b:
            x_new, step, overshot = x - 2.0 * step, 2.0 * step, True
        else:
            x_new = 0.5 * (a + b)
            step, overshot = x - x_new, False
        prev, x = abs(step), x_new
    return x


def _cubic_root(c0, c1, c2, c3):
    """A root in [0, 1] of c0 + c1 s + c2 s^2 + c3 s^3 with c0 and the sum of the c of opposite signs (a
    start for :func:`_root`): Newton's method on the cubic within the bracket, from the secant's root."""
    lo, hi, f_lo = 0.0, 1.0, c0
    f1 = c0 + c1 + c2 + c3
    s = c0 / (c0 - f1)
    for _ in range(8):
        f = c0 + s * (c1 + s * (c2 + s * c3))
        if (f > 0) == (f_lo > 0):
            lo, f_lo = s, f
        else:
            hi = s
        d = c1 + s * (2.0 * c2 + 3.0 * s * c3)
        s_new = s - f / d if d != 0.0 else -1.0
        if not (lo < s_new < hi):
            s_new = 0.5 * (lo + hi)
        if abs(s_new - s) <= 1e-12:
            return s_new
        s = s_new
    return s


#: samples per interval when a candidate interval is subdivided, and how often at most
SUBDIVIDE, DEPTH = 16, 3
#: Taylor terms of the local bound of the fourth derivative (:func:`_local_bound4`)
TAYLOR = 8


def _local_bound4(phase, Hi, ts):
    """Per interval [ts[k], ts[k + 1]] (length dt), a bound of dt^4 / 384 max |h^(4)| from the
    state at ts[k], for a phase whose own derivative bound is too crude to screen (the matrix-
    exponential path). With A_aug balanced, A_aug = D B D^-1, h^(4)(ts[k] + tau) = g B^4 e^{B tau} x
    (g = Hi D, x = D^-1 xi(ts[k])): its Taylor terms g B^(4+j) x tau^j / j! for j < TAYLOR, and the
    remainder |g B^(4+TAYLOR)| |x| e^{|B| dt} dt^TAYLOR / TAYLOR!."""
    from scipy.linalg import matrix_balance

    B, (d, _) = matrix_balance(phase.A_aug, permute=False, separate=True)
    g = np.asarray(Hi, dtype=float) * d
    for _ in range(4):
        g = g @ B
    G = [g]
    for _ in range(TAYLOR):
        G.append(G[-1] @ B)
    G = np.array(G)
    X = phase.xi(ts[:-1]) / d[:, None]
    dt = np.diff(ts)
    j = np.arange(TAYLOR)
    terms = np.abs(G[:TAYLOR] @ X) * dt[None, :] ** j[:, None] / np.array([math.factorial(i) for i in j])[:, None]
    with np.errstate(over="ignore"):
        rest = (np.linalg.norm(G[TAYLOR]) * np.linalg.norm(X, axis=0) * dt ** TAYLOR / math.factorial(TAYLOR)
                * np.exp(np.linalg.norm(B, 2) * dt))
    return (terms.sum(axis=0) + rest) * dt ** 4 / 384.0


def _screen(dt, f, hd, tol, b4, subdivide):
    """The candidate intervals of rows (f = h - thr and h' sampled, rows x samples; ``tol``, a
    scalar or per row as a column; ``b4`` per row and interval; ``subdivide`` where an interval may
    be scanned again on finer samples): (cross, turn, near), per row and interval, of :func:`_scan`.

    A crossing goes from at or above -tol to below it; a dip (h' from - to +, or a sample at the
    minimum itself) is near when its cubic, less its error bound, comes within the band (a graze
    counts); any other interval that may be subdivided is near when that reaches below the band."""
    above = f >= -tol
    cross = above[:, :-1] & ~above[:, 1:]
    turn = (hd[:, :-1] < 0) & (hd[:, 1:] >= 0)
    check = above[:, :-1] & above[:, 1:] & (turn | subdivide)
    near = np.zeros(check.shape, dtype=bool)
    if np.any(check):
        # the cubic's Hermite weights of the slopes are at most 4/27: a cheap lower bound first
        rough = np.minimum(f[:, :-1], f[:, 1:]) - 4.0 / 27.0 * dt * (np.abs(hd[:, :-1]) + np.abs(hd[:, 1:]))
        i, k = np.nonzero(check & (rough - b4 <= tol))
        if k.size:
            lo = _hermite_min(f[i, k], f[i, k + 1], hd[i, k], hd[i, k + 1], dt[k]) - b4[i, k]
            band = np.broadcast_to(tol, f.shape)[i, 0]
            hit = np.where(turn[i, k], lo <= band, lo < -band)
            # the bound b4 holds at mid-interval; at the samples the error vanishes (16 b4 s^2 (1 - s)^2):
            # an interval starting just above the band (a gap just lifted off) is judged on that
            sel = np.flatnonzero(hit & np.isfinite(b4[i, k]))
            if sel.size:   # (in floats: NumPy scalars would make each step several times dearer)
                ii, kk = i[sel], k[sel]
                cols = (f[ii, kk], f[ii, kk + 1], hd[ii, kk], hd[ii, kk + 1], dt[kk], b4[ii, kk], turn[ii, kk], band[sel])
                for j, (f0, f1, d0, d1, dtj, b4j, tj, bj) in zip(sel.tolist(), zip(*(c.tolist() for c in cols))):
                    lo_j = _envelope_min(f0, f1, d0, d1, dtj, b4j)
                    hit[j] = lo_j <= bj if tj else lo_j < -bj
            near[i[hit], k[hit]] = True
    return cross, turn, near


def _screen_row(dt, f, hd, tol: float, b4, subdivide) -> tuple[list, list, list]:
    """:func:`_screen` for one row in plain floats (cross, turn, near as lists per interval), the same
    rule: a scan's few intervals (an arming point, a subdivision's 16) cost less this way than as
    arrays. tests/test_event_search.py checks the two agree."""
    n = len(dt)
    cross, turn, near = [False] * n, [False] * n, [False] * n
    above = [x >= -tol for x in f]
    for k in range(n):
        f0, f1, d0, d1 = f[k], f[k + 1], hd[k], hd[k + 1]
        cross[k] = above[k] and not above[k + 1]
        turn[k] = d0 < 0 and d1 >= 0
        if not (above[k] and above[k + 1] and (turn[k] or subdivide[k])):
            continue
        if not min(f0, f1) - 4.0 / 27.0 * dt[k] * (abs(d0) + abs(d1)) - b4[k] <= tol:
            continue
        c0, c1, c2, c3 = _cubic(f0, f1, d0, d1, dt[k])
        lo = min([f0, f1] + [c0 + s * (c1 + s * (c2 + s * c3)) for s in _roots2(3.0 * c3, 2.0 * c2, c1)
                             if 0.0 < s < 1.0]) - b4[k]
        hit = lo <= tol if turn[k] else lo < -tol
        if hit and math.isfinite(b4[k]):
            lo = _envelope_min(f0, f1, d0, d1, dt[k], b4[k])
            hit = lo <= tol if turn[k] else lo < -tol
        near[k] = hit
    return cross, turn, near


#: at most this many intervals a scan screens in plain floats (:func:`_screen_row`), more as arrays
ROW_SCREEN = 16


def _scan(row: _Row, ts, h, hd, thr, tol, bound4=np.inf, limit=math.inf, depth=0, screen=None):
    """First root of h - thr on the samples (crossing or dip), refined; (t, graze) or None.
    Candidate intervals that start after ``limit`` (an earlier root of another row) are skipped.
    ``screen``: the (cross, turn, near) of these samples when the caller has formed them
    (:func:`_screened`, the same rule on all rows at once).

    A crossing must reach below -tol at a sample (a sample at a touching point may be a
    round-off below zero: that is a dip, not a crossing). A dip (h' from - to + with h
    above -tol at both samples) is refined only when the Hermite cubic through the samples
    comes within its interpolation error bound (``bound4``, per interval or for all) of zero. Any
    other interval whose cubic comes that close (h' may change sign twice between samples: a fast
    component turning a slow descent around, e.g. right after a neighbouring contact closed) is
    subdivided into :data:`SUBDIVIDE` samples and scanned again (the bound shrinks by 16^4): a dip
    below zero between two samples that both descend is not missed. A root found in a crossing
    interval is the first one only if the row certainly stays above -tol before it (:func:`first`);
    otherwise the interval is subdivided too (three roots: the refinement may return the last), and so is a
    dip interval whose row may not be convex (two minima: the refinement may return either, or the maximum
    between). Finer samples and roots come from ``row`` (the whole row: no term left out).""" 
    if ts.size < 2:
        return None
    f = h - thr
    # a row can cross below its band and come back between two samples whatever their slopes (h'
    # - + -, or + - + right after a lift): such an interval is subdivided when the cubic, less its
    # error bound, reaches below the band. A bound4 that the remaining levels cannot bring down to
    # the band screens nothing: subdividing on it would multiply the work. When the phase's bound is
    # that crude (the matrix-exponential path's, 1e32 tol), a local one is formed from the states
    reach = tol * float(SUBDIVIDE) ** (4 * (DEPTH - depth))
    b4 = np.broadcast_to(np.asarray(bound4, dtype=float), (ts.size - 1,))
    if depth == 0 and not np.all(b4 <= reach):
        b4 = np.minimum(b4, _local_bound4(row.phase, row.H, ts))
    subdivide = (b4 <= reach) if depth < DEPTH else np.zeros(ts.size - 1, dtype=bool)
    dt = np.diff(ts)
    if screen is not None:
        cross, turn, near = screen
    elif dt.size <= ROW_SCREEN:
        cross, turn, near = _screen_row(dt.tolist(), f.tolist(), hd.tolist(), float(tol), b4.tolist(),
                                        subdivide.tolist())
    else:
        cross, turn, near = (x[0] for x in _screen(dt, f[None], hd[None], tol, b4[None], subdivide[None]))
    if isinstance(cross, np.ndarray):
        cross, near = np.flatnonzero(cross).tolist(), np.flatnonzero(near).tolist()
    else:
        cross, near = [k for k, c in enumerate(cross) if c], [k for k, x in enumerate(near) if x]
    k_c = cross[0] if cross else None
    cand = [k for k in near if k_c is None or k < k_c]
    if k_c is None and not cand:
        return None

    def fun(t):
        h_t, hd_t = row.at(t)
        return h_t - float(thr), hd_t

    def finer(k):
        sub = np.linspace(ts[k], ts[k + 1], SUBDIVIDE + 1)
        hh = row.samples(sub)
        return _scan(row, sub, hh[0], hh[1], thr, tol, b4[k] / SUBDIVIDE**4, limit, depth + 1)

    def first(k, t_r):
        """t_r, or the earlier root a finer scan finds when t_r may not be the first: certain when
        the row decreases up to t_r (:func:`_first_root`), or when the cubic over [ts[k], t_r] alone
        (its error bound smaller by ((t_r - ts[k]) / dt)^4: a root just after a rebound off the
        band) stays above -tol."""
        if not subdivide[k] or _first_root(f[k], f[k + 1], hd[k], hd[k + 1], dt[k], (t_r - ts[k]) / dt[k], b4[k],
                                           tol):
            return t_r, False
        u = (t_r - ts[k]) / dt[k]
        if u > 0.0:
            hr = row.at(t_r)
            if _envelope_min(f[k], hr[0] - thr, hd[k], hr[1], t_r - ts[k], b4[k] * u**4) >= -tol:
                return t_r, False
        res = finer(k)
        return (t_r, False) if res is None else res

    for k in cand + ([k_c] if k_c is not None else []):
        a, b = ts[k], ts[k + 1]
        if a > limit:
            return None
        if subdivide[k] and k != k_c and not turn[k]:
            res = finer(k)
            if res is not None:
                return res
            continue
        if k == k_c:
            if row.value(a) - thr < 0:  # the sample before is itself (round-off) below: the root is there
                return a, False
            t_r = _root(fun, a, b)
            return first(k, b if t_r is None else t_r)
        if not turn[k]:
            continue
        if subdivide[k] and not _convex(f[k], f[k + 1], hd[k], hd[k + 1], dt[k], b4[k]):
            # h' may change sign three times: the interval may hold two minima, the refinement would
            # find one of them (or the maximum between): scanned again on finer samples
            res = finer(k)
            if res is not None:
                return res
            continue
        # dip: the minimum inside [a, b]
        tm = _root(row.slope, a, b)
        if tm is None:  # h' is round-off at an end: take the lower end sample
            tm = a if f[k] <= f[k + 1] else b
        fm = row.value(tm) - thr
        if fm < -tol:   # (decreasing up to the minimum, the only one: the root is the first)
            t_r = _root(fun, a, tm)
            return (tm if t_r is None else t_r), False
        if fm <= tol and thr == 0.0:
            return tm, True
    return None


def _polynomial_event(phase: Phase, rows: Rows, t_start: float, t_stop: float) -> Event | None:
    """Rigid-body phases (A nilpotent, constant load): every row is a polynomial in
    tau = t - t_start with coefficients H A_aug^k xi0 / k!; its real roots are the events."""
    xi0 = phase.xi(t_start)
    coef, term, k = [], xi0.copy(), 0
    while np.any(term) and k <= phase.dim + 1:
        coef.append(rows.H @ term / math.factorial(k))
        term = phase.A_aug @ term
        k += 1
    C = np.array(coef).T  # rows x degree+1, increasing powers
    T = t_stop - t_start
    # the size of the terms over the horizon (each power at its largest)
    tol = ZERO * (np.abs(C) @ (max(T, 1.0) ** np.arange(C.shape[1])) + 1e-300)
    def real_roots(c):
        nz = np.flatnonzero(np.abs(c) > 0)
        if nz.size == 0 or nz[-1] == 0:
            return np.zeros(0)
        roots = np.roots(c[: nz[-1] + 1][::-1])
        return np.sort(roots[(np.abs(roots.imag) <= 1e-9 * np.abs(roots)) & (roots.real > 0)].real)

    best = None

    def keep(hit, i):
        nonlocal best
        if best is None or hit[0] < best[0][0] - 1e-12 * max(1.0, abs(hit[0])):
            best = (list(hit), [i])
        elif abs(hit[0] - best[0][0]) <= 1e-12 * max(1.0, abs(hit[0])):
            best[1].append(i)

    for i in range(rows.size):
        c = C[i].copy()
        start_in_band = abs(c[0]) <= tol[i]
        c0 = c.copy()
        if start_in_band:
            c0[0] = 0.0
            # leaving the band downwards before ever rising above it: root of h + band, with the
            # band sized by the terms at that time (a rigid rebound is resolved however small)
            band, tau = tol[i], None
            for _ in range(3):
                cb = c0.copy()
                cb[0] = band
                down = [x for x in real_roots(cb) if x <= T * (1 + 1e-15)]
                if not down:
                    tau = None
                    break
                tau = down[0]
                local = ZERO * (abs(c[0]) + float(np.abs(c[1:]) @ tau ** np.arange(1, c.size))) + 1e-300
                if local >= band:
                    break
                band = local
            if tau is not None:
                ext = [x for x in real_roots(np.polynomial.polynomial.polyder(c0)) if x < tau]
                if max(np.polynomial.polynomial.polyval(np.array(ext + [tau]), c0), default=0.0) <= band:
                    keep((t_start + tau, False, True), i)
                    continue
        val = lambda tau: np.polynomial.polynomial.polyval(tau, c0)  # noqa: E731
        for tau in real_roots(c0):
            if tau > T * (1 + 1e-15):
                break
            if start_in_band and tau <= 1e-12 * T:
                continue
            d = 1e-7 * max(tau, T * 1e-9)
            after, before_ = val(tau + d), val(max(tau - d, 0.0))
            if after < 0:
                keep((t_start + tau, False, False), i)
            elif before_ >= 0 and after >= 0:
                keep((t_start + tau, True, False), i)   # touches zero without crossing: a graze
            else:
                continue
            break
    if best is None:
        return None
    (t_e, graze, in_band), idx = best
    return Event(float(t_e), idx, [graze] * len(idx), tol, [in_band] * len(idx))
