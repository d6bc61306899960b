"""The contact LCPs (28), (29) and (30-32): one block structure, three right-hand sides.

All three eliminate the coordinates through one operator S = X^-1 (X = Q for the
stationary problem, X = M for transitions and impacts) and read

    0 <= [ J_N^T S W_N   J_N^T S J_T   0 ] (lam_N)   (b_N)     (lam_N)
         [ J_T^T S W_N   J_T^T S J_T   E ] (beta ) + (b_T) _|_ (beta ) >= 0
         [ mu            -E^T          0 ] (z    )   ( 0 )     (z    )

with the friction generators J_T = [S_k B_k] and E of :class:`~nsfem.contact.set.ContactSet`.
W_N = J_N except for contacts that already slide (transition LCP only), where the normal
force drags its friction force along: W_N,k = J_N,k + mu_k S_k e_k with e_k the cone
generator opposing the slip velocity. Only the contacts given as ``normal`` enter (the
ones that can be active); tangential unknowns exist only for ``friction`` contacts.

=============  ========  =======================================  ==========================
LCP            X         b_N                                      b_T
=============  ========  =======================================  ==========================
stationary 28  Q         j_N + J_N^T Q^-1 f0 (gap under f0)       J_T^T Q^-1 f0 (slip under f0)
transition 29  M         J_N^T M^-1 f*   (gap acceleration)       J_T^T M^-1 f*
impact 30-32   M         g'^- + eps min(g'^-, 0), g'^- = J_N^T q'^-   J_T^T q'^-
=============  ========  =======================================  ==========================

with f* = f(t) - C q' - Q q. The solution x gives the generalized contact force
W x (``force``) and its response S W x (``response``): the displacement, acceleration or
velocity change added to the unconstrained one.

>>> import numpy as np
>>> from nsfem.contact.set import ContactSet
>>> from nsfem.linalg import factorize
>>> cs = ContactSet.from_arrays([[1.0]], [0.0])           # one dof, gap g = q
>>> lcp = stationary_lcp(cs, factorize(np.array([[2.0]])), np.array([-4.0]))
>>> x = lcp.solve().x                                      # a spring pushed onto a stop
>>> x.tolist(), lcp.motion(x).tolist()
([4.0], [0.0])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..contact.set import ContactSet
from ..errors import NsfemError
from ..linalg import Factorization
from .compiled import lemke_one as compiled_one
from .pivoting import LCPResult, _kernels, equilibrate, lemke

#: relative size (to the largest right-hand side entry) below which an entry is round-off
ROUND_OFF = 1e-13


@dataclass(frozen=True)
class ContactLCP:
    """LCP(A, b) of a contact problem and the maps back to forces and motion."""

    A: np.ndarray
    b: np.ndarray
    normal: np.ndarray          # contact indices of the normal unknowns lam_N
    friction: np.ndarray        # contact indices with tangential unknowns beta (subset of normal)
    r: np.ndarray               # generators per friction contact
    W: np.ndarray               # force columns [W_N, J_T] (n x (m_a + p))
    Y: np.ndarray               # S W
    generators: tuple           # B_k per friction contact
    base: np.ndarray            # the motion without contact forces: Q^-1 f0, M^-1 f* or q'^-
    scales: tuple | None = None  # Lemke's equilibration of A, when built once for many solves
    row_groups: np.ndarray | None = None   # :attr:`groups` when formed once with a cached matrix part

    @property
    def size(self) -> int:
        return self.b.size

    @property
    def groups(self) -> np.ndarray:
        """Row kinds for the certificate: 0 motion rows (gaps, slips), 1 friction limits."""
        if self.row_groups is not None:
            return self.row_groups
        return _groups(self.size, self.friction.size)

    def solve(self, **kw) -> LCPResult:
        """Lemke's method on (A, b); keywords go to :func:`~nsfem.lcp.pivoting.lemke`."""
        if not kw and self.b.size == 1 and self.scales is not None:   # most impacts: one contact
            one = _one_unknown(self)
            if one is not None:
                return one
        kw.setdefault("groups", self.groups)
        if self.scales is not None:
            kw.setdefault("scales", self.scales)
        return lemke(self.A, self.b, **kw)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lam_N, beta, z) from the LCP unknowns x."""
        m = self.normal.size
        p = self.W.shape[1] - m   # W = [W_N, J_T]: J_T has the sum of r_k columns
        return x[:m], x[m:m + p], x[m + p:]

    def force(self, x: np.ndarray) -> np.ndarray:
        """Generalized contact force W_N lam_N + J_T beta (n,)."""
        return self.W @ x[: self.W.shape[1]]

    def response(self, x: np.ndarray) -> np.ndarray:
        """S (W_N lam_N + J_T beta): what the contact forces add to q, q'' or q' (n,)."""
        return self.Y @ x[: self.Y.shape[1]]

    def motion(self, x: np.ndarray) -> np.ndarray:
        """q (stationary), q'' (transition) or q'^+ (impact): ``base`` + ``response(x)``."""
        return self.base + self.response(x)

    def tangential(self, x: np.ndarray) -> list[np.ndarray]:
        """Tangential force lam_T,k = B_k beta_k of each friction contact (d_k components)."""
        _, beta, _ = self.split(x)
        out, row = [], 0
        for B, rk in zip(self.generators, self.r):
            out.append(B @ beta[row:row + rk])
            row += rk
        return out


def _one_unknown(lcp: ContactLCP) -> LCPResult | None:
    """:func:`~nsfem.lcp.pivoting.lemke`'s result on an LCP of one unknown with its cached equilibration,
    straight from the compiled kernel (what lemke's compiled path does after checking its arguments, which
    a cached matrix part has passed: finite A, valid scales); None where that path would not take it (the
    reference core, a non-finite b, scaled entries near overflow, the kernel declining): lemke decides."""
    lib = _kernels()
    if lib is None:
        return None
    a, b = float(lcp.A[0, 0]), float(lcp.b[0])
    r_s, c_s = float(lcp.scales[0][0]), float(lcp.scales[1][0])
    if not (math.isfinite(a) and math.isfinite(b) and 0.0 < r_s < math.inf and 0.0 < c_s < math.inf):
        return None
    if not math.isfinite(lib.scaled_size(lcp.A, lcp.b, *lcp.scales)):
        return None
    return compiled_one(lib, a, b, r_s, c_s, 1.0, 1e-11)


def _groups(size: int, friction: int) -> np.ndarray:
    """:attr:`ContactLCP.groups` of an LCP of ``size`` unknowns with ``friction`` friction contacts."""
    g = np.zeros(size, dtype=int)
    g[size - friction:] = 1
    return g


def contact_lcp(solve: Factorization, cs: ContactSet, normal, friction, bN, bT, slide=None,
                base: np.ndarray | None = None, extra=None, cache: LCPCache | None = None, key=None) -> ContactLCP:
    """Assemble the LCP of the module docstring.

    ``normal``: contact indices with a normal unknown; ``friction``: those of them with
    tangential unknowns (mu > 0); ``slide``: {contact: unit tangent-plane vector of its
    friction force} for contacts that slide (their friction is not an unknown).
    ``extra``: {contact: generalized force (n,) per unit lam_N added to its normal column}
    (a friction force of fixed direction given in the full coordinates).

    ``cache``, ``key``: the matrix part (W, S W, A and its equilibration) depends only on the
    operator, the contact set and the structure (normal, friction, slide, extra); a caller that
    meets the same structure again (an event-driven run: one per pair of configurations) passes
    an :class:`LCPCache` and a hashable ``key`` that identifies that structure, and only the
    right-hand side is formed anew. The cached arrays are read-only.
    """
    normal = np.asarray(normal, dtype=int).ravel()
    friction = np.asarray(friction, dtype=int).ravel()
    bN, bT = (np.asarray(x, dtype=float).ravel() for x in (bN, bT))
    return _assemble(_parts(solve, cs, normal, friction, slide or {}, extra, cache, key), cs, normal, friction,
                     bN, bT, base)


def _parts(solve: Factorization, cs: ContactSet, normal, friction, slide, extra, cache, key) -> tuple:
    """The matrix part of :func:`contact_lcp`, from ``cache`` under ``key`` when there (else built,
    and kept when both are given)."""
    keep = cache is not None and key is not None
    entry = cache.get(key) if keep else None
    if entry is None:
        entry = _matrix_part(solve, cs, normal, friction, slide, extra, keep)
        if keep:
            cache.put(key, entry, sum(a.nbytes for a in entry[:3] + entry[6:]))
    return entry


def _impact_parts(solve: Factorization, cs: ContactSet, active, cache, key) -> tuple:
    """(matrix part, normal, friction) of the impact LCP over ``active``; a cached matrix part keeps its
    index arrays (its key names the contacts), so an event that meets the structure again forms neither."""
    entry = cache.get(key) if cache is not None and key is not None else None
    if entry is None:
        normal = np.asarray(active, dtype=int).ravel()
        friction = np.array([k for k in normal if cs.r[k] > 0], dtype=int)
        entry = _parts(solve, cs, normal, friction, {}, None, cache, key)
    return entry, entry[9], entry[10]


def _assemble(entry: tuple, cs: ContactSet, normal, friction, bN, bT, base) -> ContactLCP:
    """:class:`ContactLCP` of a matrix part and the right-hand side (bN, bT)."""
    A, W, Y, r, generators, scales = entry[:6]
    groups = entry[8]
    # a list: a few entries, read twice (impact_lcp's lists of floats are taken as they are)
    b = ((bN if type(bN) is list else np.asarray(bN, dtype=float).ravel().tolist())
         + (bT if type(bT) is list else np.asarray(bT, dtype=float).ravel().tolist()) + [0.0] * friction.size)
    # entries at round-off of the largest (J^T X^-1 f carries cond * eps of it) are zeros: a
    # symmetric structure's midspan slip, say; left alone they make Lemke chase 1e-18 m
    big = math.nan if any(e != e for e in b) else max(map(abs, b), default=0.0)   # as numpy: a nan zeroes nothing
    b = np.array([0.0 if abs(e) <= ROUND_OFF * big else e for e in b])
    return ContactLCP(A, b, normal, friction, r, W, Y, generators,
                      np.zeros(cs.n) if base is None else np.asarray(base, dtype=float), scales, groups)


class LCPCache:
    """Matrix parts of contact LCPs by structure (:func:`contact_lcp`): at most ``entries`` of them
    and ``nbytes`` in all, the oldest dropped first (an unreduced model's M^-1 W is n x contacts)."""

    def __init__(self, entries: int = 256, nbytes: int = 2 ** 27):
        self.entries, self.nbytes = int(entries), int(nbytes)
        self._items: dict = {}
        self._size = 0

    def __len__(self) -> int:
        return len(self._items)

    def get(self, key):
        hit = self._items.get(key)
        return None if hit is None else hit[0]

    def put(self, key, entry, nbytes: int) -> None:
        if nbytes > self.nbytes or key in self._items:
            return
        while self._items and (len(self._items) >= self.entries or self._size + nbytes > self.nbytes):
            old = next(iter(self._items))
            self._size -= self._items.pop(old)[1]
        self._items[key] = (entry, nbytes)
        self._size += nbytes


def _matrix_part(solve: Factorization, cs: ContactSet, normal, friction, slide, extra, keep: bool):
    """(A, W, S W, r, generators, equilibration or None, J_N of the normal contacts, J_T, the rows'
    groups, normal, friction) of :func:`contact_lcp` (J_N and J_T give the right-hand sides' rows);
    read-only when ``keep`` (cached), with the equilibration computed then."""
    JN = cs.JN[:, normal]
    WN = JN.copy()
    for j, k in enumerate(normal):
        if int(k) in slide:
            WN[:, j] += cs.mu[k] * (cs.JS[k] @ np.asarray(slide[int(k)], dtype=float))
        if extra and int(k) in extra:
            WN[:, j] += np.asarray(extra[int(k)], dtype=float)
    JT = cs.JT(friction)
    E = cs.E(friction)
    W = np.hstack([WN, JT])
    Y = solve.solve(W)
    D = np.hstack([JN, JT]).T @ Y
    m, p, f = normal.size, JT.shape[1], friction.size
    A = np.zeros((m + p + f, m + p + f))
    A[: m + p, : m + p] = D
    A[m: m + p, m + p:] = E
    pos = {int(k): j for j, k in enumerate(normal)}
    for i, k in enumerate(friction):
        A[m + p + i, pos[int(k)]] = cs.mu[k]
    A[m + p:, m: m + p] = -E.T
    scales = None
    groups = _groups(A.shape[0], f)
    if keep:
        scales = equilibrate(A) if A.size and np.all(np.isfinite(A)) else None
        normal, friction = normal.copy(), friction.copy()
        for arr in (A, W, Y, JN, JT, groups, normal, friction):
            arr.setflags(write=False)
    return (A, W, Y, cs.r[friction], tuple(cs.generators(int(k)) for k in friction), scales, JN, JT, groups,
            normal, friction)


def stationary_lcp(cs: ContactSet, Q: Factorization, f0: np.ndarray | None, normal=None,
                   slide=None) -> ContactLCP:
    """LCP (28): the stationary contact state under the constant load f0.

    Friction as in the paper's section 3.1: tangential displacements start at zero and
    grow monotonically, so the friction force opposes the tangential displacement.
    ``slide`` maps contacts that slide whatever the state (a moving surface: the slip velocity
    Sq^T q + w of a state at rest keeps its direction) to the unit direction of their friction
    force, which is then no unknown: LCP (28) with sliding friction of known direction.
    The solution is q = Q^-1 f0 + ``response(x)`` = ``motion(x)``.
    """
    normal = np.arange(cs.m) if normal is None else np.asarray(normal, dtype=int)
    slide = {int(k): np.asarray(d, dtype=float).ravel() for k, d in (slide or {}).items()}
    q0 = np.zeros(cs.n) if f0 is None else Q.solve(f0)
    friction = np.array([k for k in normal if cs.r[k] > 0 and int(k) not in slide], dtype=int)
    return contact_lcp(Q, cs, normal, friction, cs.gaps(q0)[normal], cs.JT(friction).T @ q0, slide=slide,
                       base=q0)


def transition_lcp(cs: ContactSet, M: Factorization, fstar: np.ndarray, closed, stick, slide=None,
                   extra=None, cache: LCPCache | None = None, key=None, v: np.ndarray | None = None) -> ContactLCP:
    """LCP (29): which closed contacts stay closed, which stick and which slip.

    ``fstar`` = f(t) - C q' - Q q; ``closed`` contacts have g = g' = 0; ``stick`` are the
    closed frictional ones at zero slip velocity; ``slide`` maps the others to the
    direction of their friction force; ``extra`` adds a generalized force per unit lam_N to
    a closed contact's normal column (see :func:`contact_lcp`). Accelerations:
    q'' = M^-1 f* + ``response(x)``. ``cache``, ``key``: see :func:`contact_lcp`. ``v``: q', for
    the part Sq^T q' a moving surface adds to the slip acceleration.
    """
    closed = np.asarray(closed, dtype=int)
    stick = np.array([k for k in stick if cs.r[k] > 0], dtype=int)
    slide = {int(k): np.asarray(d, dtype=float).ravel() for k, d in (slide or {}).items()}
    parts = None if cache is None or key is None else cache.get(key)
    if parts is None:   # a cached structure was checked when built
        _check_transition(cs, closed, stick, slide, extra)
        parts = _parts(M, cs, closed, stick, slide, extra, cache, key)
    a0 = M.solve(fstar)
    bT = _with_surface(cs, stick, parts[7].T @ a0, v, cs.surface_drifts,
                       "transition LCP: a moving surface's slip acceleration needs the velocity v") if stick.size else ()
    return _assemble(parts, cs, closed, stick, parts[6].T @ a0, bT, a0)


def _with_surface(cs: ContactSet, friction: np.ndarray, bT: np.ndarray, x, part, missing: str) -> np.ndarray:
    """b_T plus what a moving surface adds to the slip rows of ``friction`` (``part(friction, x)``: its slip
    velocity at q, or its slip acceleration at q'); ``x`` is needed only when one of them moves."""
    if not np.any(cs.moving[friction]):
        return bT
    if x is None:
        raise NsfemError(missing)
    return bT + part(friction, x)


def _check_transition(cs: ContactSet, closed, stick, slide: dict, extra) -> None:
    """Raise NsfemError unless sticking and sliding contacts are closed, none does both, slide
    directions are unit tangent vectors and extra forces belong to closed contacts."""
    where = set(int(k) for k in closed)
    for k in set(int(k) for k in stick) | set(slide):
        if k not in where:
            raise NsfemError(f"transition LCP: contact {k} sticks or slides but is not closed")
    for k, d in slide.items():
        if k in set(int(j) for j in stick):
            raise NsfemError(f"transition LCP: contact {k} cannot both stick and slide")
        if d.shape != (cs.JS[k].shape[1],) or not abs(np.linalg.norm(d) - 1.0) < 1e-9:
            raise NsfemError(f"transition LCP: the slide direction of contact {k} must be a unit vector with "
                             f"{cs.JS[k].shape[1]} components (its tangent directions)")
    for k in extra or {}:
        if int(k) not in where or np.shape(extra[k]) != (cs.n,):
            raise NsfemError(f"transition LCP: the extra force of contact {k} needs a closed contact and {cs.n} "
                             "components")


def impact_lcp(cs: ContactSet, M: Factorization, v: np.ndarray, active, cache: LCPCache | None = None,
               key=None, eps: np.ndarray | None = None, q: np.ndarray | None = None) -> ContactLCP:
    """LCP (30-32): impulses with Newton restitution and frictional impulses.

    ``active`` are the contacts closed or just closing at the impact (g = 0); ``v`` the
    velocity before it. After the impact q'^+ = q'^- + ``response(x)`` satisfies
    0 <= g'^+ + eps g'^- _|_ Lambda_N >= 0 and the tangential impact law (33). ``cache``, ``key``:
    see :func:`contact_lcp` (the restitutions eps enter only the right-hand side); ``eps``: the
    restitutions per contact to use instead of the contact set's; ``q``: the configuration, for the
    slip velocity a moving surface adds (eq. 32: the tangential law acts on the slip velocity after the
    impact, J_T^T q'^+ + g_0T').
    """
    parts, active, friction = _impact_parts(M, cs, active, cache, key)
    e = (cs.eps if eps is None else np.asarray(eps, dtype=float)).tolist()
    # Newton's law acts on approaching contacts; a separating one must merely not approach
    # (min(g', 0) as numpy's: nan stays nan, -0.0 gives 0.0)
    bN = [g + e[k] * (g if g < 0.0 or g != g else 0.0) for g, k in zip((parts[6].T @ v).tolist(), active.tolist())]
    bT = _with_surface(cs, friction, parts[7].T @ v, q, cs.surface_offsets,
                       "impact LCP: a moving surface's slip velocity needs the configuration q") if friction.size else []
    return _assemble(parts, cs, active, friction, bN, bT, v)
