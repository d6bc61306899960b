"""Pseudo-arclength continuation of a branch of solutions of r(u, p) = 0, with its folds and the points
where its stability changes.

Generic: it knows nothing of rotors. For periodic orbits the residual is the shooting residual
r(x0, p) = phi_T(x0; p) - x0 with J_u = monodromy - I, and ``stability`` returns the monodromy's
eigenvalues (the Floquet multipliers); any map's fixed points fit the same mould.

Method (Keller 1977, "Numerical solution of bifurcation and nonlinear eigenvalue problems"; Kuznetsov,
"Elements of Applied Bifurcation Theory", 3rd ed. 2004, chapter 10). The unknowns are scaled,
z = (u / u_scale, (p - p0) / (p_end - p0)), so that p_end is z_p = 1 and arclength counts a change of
u by u_scale as much as the whole range of p. With J = [J_u u_scale | J_p (p_end - p0)] (m x (m+1)):

- tangent: the null vector of J, from the bordered system [[J], [t_prev^T]] t = [0, 1] (normalised;
  its sign continues the previous direction, t.t_prev > 0); the first one points to p_end;
- predictor z + ds t; corrector: Newton on the bordered system
  [[J_u, J_p], [t_u^T, t_p]] dz = -[r, t.(z - z_pred)], regular at folds of the branch (where J_u
  alone is singular), so folds pass naturally;
- step control: a failed correction (no convergence in ``max_iter`` Newton steps, a non-finite
  residual, an error of the residual or the stability, a corrector that moved farther than the step,
  or a tangent turned by more than 45 degrees) halves ds; a step that converged in at most 2
  iterations with the tangent turned by less than 10 degrees grows it by 1.5; ds is bounded by
  ``max_step`` and ``min_step``, lengths in units of p (the predictor changes p by at most
  ``max_step`` and u by at most ``max_step / |p_end - p0|`` times u_scale; the corrected point lies
  within sqrt(2) ds of the previous one);
- the branch stops at p_end (the last point corrected at p = p_end exactly), when it leaves
  [min(p0, p_end) - margin, max(p0, p_end) + margin] after folding back, when it returns to its first
  point (a closed branch: seen in the unknowns while they are in the first step's coordinates, after a later
  ``reanchor`` in the caller's coordinate-free ``invariant`` and p; without one such a branch runs on to
  ``max_steps``), after ``max_steps`` steps, or when a correction fails at ``min_step``;
  :attr:`Branch.stop` and :attr:`Branch.reason` say which and where.

Grazing (``events``: each corrected point's structure, a hashable such as an orbit's events, and its margin >= 0 to
a change of it, 0 at a grazing and linear in the distance on either side). Across a change of structure the branch
has a kink, and next to it the corrector may have no basin (Nordmark's square-root map: an impacting orbit's J_u
grows like 1/u with its impact speed u), so that steps halve down to ``min_step``. A step that lands on another
structure is accepted whatever its tangent's turn (the kink's) when the two sides' tangent lines meet between its
ends, and for a turn over 10 degrees not far short of where the margin falls to 0 (:func:`_kink_joins`), and the
grazing is recorded bracketed by it (``located`` False); else it landed on the other structure's far arm past a fold
next to the grazing (the branch turning back there: Nordmark's square root with the other sign), and the step is a
failed one that looks for the grazing, a point past it only counting when its own tangent leads back to the grazing
(:func:`_joins`): the branch does not continue back through the turn (no start on that side is known), so it stops
"failed" at the grazing rather than skip the folds and the segment between them. A fold of the far side smaller than
the step passes unseen, as a smooth branch's would. A step that fails from a point whose margin is below
NEAR_MARGIN, or falls to 0 within
GRAZE_REACH steps, looks for the grazing (:func:`_graze_point`: secants on the margin from the side the branch is
on, to GRAZE_LOCATE of ``locate_tol``), then for the first point past it (:func:`_beyond`: at a fixed p a step
further, from the grazing point, its extrapolation or the caller's ``solve``; brought back towards it by
:func:`_nearer`), locates the grazing from that side too and keeps the better; the grazing point becomes a point
of the branch, recorded as kind "grazing" (``located`` True, its ``accuracy``, ``structure_before``/``after``),
and the branch goes on from the point past it with that side's tangent, at the step it had before. No multiplier
crossing is looked for across a located grazing (the multipliers jump there: each side's verdict is its own); over
a step that passed one, a crossing whose final bracket straddles the change of structure is that jump, not counted.

Special points between two consecutive points A and B, located along the chord AB by bracketing the sign
change of a test function (regula falsi, Illinois variant, with bisection steps whenever the bracket
does not halve in two; each trial point re-corrected onto the branch with the constraint
d.(z - z_trial) = 0, d the chord's unit vector) until the bracket's chord is shorter than
``locate_tol`` (in units of p). The crossing lies on the branch between the final bracket's corrected
ends; the located point is the end with the smaller |test function|, its "accuracy" the distance to the
other end (in units of p), so |p - p*| <= accuracy, plus the corrector's error (u off the branch by
about tol / |J_u|, moving the test function accordingly):

- fold of the branch: where the tangent's p component changes sign (Kuznetsov's test function
  psi = t_p, chapter 10);
- with ``stability``: where a multiplier crosses the unit circle (|mu| = 1 exactly; a multiplier counts
  as outside when |mu| > 1 + unit_tol, which keeps neutral multipliers at |mu| = 1 +- round-off from
  making false alarms). Multipliers of A and B are paired by the least sum of sqrt(distance) (where their
  counts differ the missing ones are zeros: a direction held at one point, as an orbit's contact held
  closed on its section, has multiplier 0 there); each pair on
  different sides is a claimed crossing. Two multipliers on different sides passing near each other within
  the step may be paired crosswise (a spurious pair of crossings), so each claim is checked: its stretch
  of the chord is halved (trial points with their multipliers, at least one) until the followed
  multiplier moved less than a quarter of its distance to every other one; a claim that vanishes on the way
  was an exchange. Where nothing is claimed but a multiplier's pairing is ambiguous with one on the other side of
  the circle (:func:`_straddles`), the two may have swapped sides (one out, one in: no claim at the ends), so one
  trial point is taken there too. One that stays ambiguous counts only where the number outside the circle (by kind)
  changed. A real crossing is then followed through the trial points by the same pairing. Kinds: a real
  multiplier through +1 "fold", through -1 "period-doubling", a complex pair "neimark-sacker"
  (Kuznetsov chapter 4). A saddle-node (a fold of the branch with its multiplier through +1)
  is recorded once, as the tangent's fold.

:func:`critical_vector` gives the eigenvector of the multiplier closest to -1 (or any target) of a
monodromy-like matrix, for starting the doubled orbit at u + h v after a period doubling.

>>> import numpy as np
>>> def circle(u, p):   # x^2 + p^2 = 1
...     return np.array([u[0] ** 2 + p ** 2 - 1]), np.array([[2 * u[0]]]), np.array([2 * p])
>>> b = continue_branch(circle, [-0.6], -0.8, 0.8, step=0.05)
>>> b.stop, b.points[-1].p, [round(x["value"], 6) for x in b.bifurcations]
('end', 0.8, [])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import NsfemError

Residual = Callable[[np.ndarray, float], tuple]
Stability = Callable[[np.ndarray, float], np.ndarray]

#: a correction whose tangent turned by more than this is refused (the step halved): the corrector
#: may have jumped to another branch
MAX_TURN_COS = math.cos(math.radians(45.0))
#: a step converged in at most GROW_ITERATIONS Newton steps with a turn below this grows by GROW
EASY_TURN_COS = math.cos(math.radians(10.0))
GROW_ITERATIONS = 2
GROW = 1.5
#: a multiplier is real (for the kind of a crossing) when |Im mu| <= REAL_TOL max(1, |mu|): LAPACK
#: returns real eigenvalues of a real matrix with Im exactly 0; a genuine pair near +-1 has
#: |Im mu| ~ sqrt(distance to the collision), far above round-off
REAL_TOL = 1e-7
#: lengths below this share of |p_end - p0| (steps, locate_tol) are refused: the scaled unknowns are
#: O(1), and steps near their round-off (2.2e-16) make no progress
ROUNDOFF = 1e-12
#: at most this many trial points to follow the multipliers across one step where the pairing of its ends is
#: ambiguous (halvings: 2^-5 of the step where the multipliers pass each other, more trial points near the passage)
MAX_FOLLOW = 24
#: a multiplier's pairing across a stretch of the branch is unambiguous when it moved less than this share of its
#: distance to every other multiplier
RESOLVED = 0.25
#: a tangent whose p component is below this (in scaled units) is at a fold of the branch: moved to new coordinates
#: without du_new/dp, it is oriented by the change's M (its p component's sign is round-off there)
FOLD_TP = 1e-3
#: a point whose margin to a change of its structure (``events``) is below this may have a grazing within any step
NEAR_MARGIN = 1e-2
#: ... or one whose margin, falling along the branch as it did from the point before, reaches 0 within this many
#: steps: a step that fails from there looks for the grazing first
GRAZE_REACH = 4.0
#: a step over a change of structure whose two sides' tangent lines meet short of this share of the way to where the
#: side's margin, falling as it did, reaches 0 is no kink of one branch (:func:`_kink_joins`)
SHORT_OF_ZERO = 0.5
#: at most this many trial points to locate a grazing from one side, and at most this many failed in a row
MAX_GRAZE_TRIALS = 20
#: a grazing is located to this share of locate_tol: its margin is smooth on the side it is approached from, where
#: the secant converges superlinearly (a few trial points more for three more digits)
GRAZE_LOCATE = 1e-3
GRAZE_FAILS = 5
#: each trial aims at this share of the secant's distance to the grazing (from the side it is approached from;
#: a trial past it may fail to correct: Nordmark's square-root map has no linear neighbourhood there)
GRAZE_AIM = 0.9
#: the first point past a grazing is brought back towards it by at most this many halvings of its distance
NEARER = 6
#: at most this many trial points per special point (the bracket at least halves every three: 2^-33 of
#: the chord at worst, 1e-10; a smooth test function takes 5 to 10)
MAX_TRIALS = 100


@dataclass
class BranchPoint:
    """One point of a branch: the parameter, the unknowns, their stability."""

    p: float                          # the parameter
    u: np.ndarray                     # the unknowns (for an orbit: the section state)
    multipliers: np.ndarray | None    # complex, sorted by modulus, largest first (None without stability)
    stable: bool | None               # every |mu| < 1 + unit_tol (None without stability)
    converged: bool                   # max |r(u, p)| <= tol
    residual: float = math.nan        # max |r(u, p)| at the point
    s: float = 0.0                    # arclength from the first point, in units of p (along the chords)
    anchor: int = 0                   # the coordinates u is in: the number of re-anchorings before it


@dataclass
class Branch:
    """A continued branch, its special points and why it ended."""

    points: list[BranchPoint]
    bifurcations: list[dict] = field(default_factory=list)
    # {"kind": "fold" | "period-doubling" | "neimark-sacker", "value": p, "index": i (between points i
    #  and i + 1), "u": u there, "multipliers": at the point or None, "accuracy": its distance (units
    #  of p) to the other end of the final bracket (the crossing lies on the branch between them),
    #  "detected_by": "tangent" | "multipliers"}; a "grazing" (``events``: the structure changed) has "detected_by"
    #  "events", "located" (False: bracketed by a step, "index" between its points; True: point index + 1 is the
    #  grazing orbit), "structure_before", "structure_after" and "margin" (the located point's)
    stop: str = ""      # "end" | "left" | "closed" | "max_steps" | "failed"
    reason: str = ""    # one sentence: where and why the branch ended
    # the changes of coordinates (``reanchor``): {"index": the point (its u in the old coordinates; the next
    #  points in the new), "value": p, "anchor": the new coordinates' number, "forced": after a failed step,
    #  "multipliers_before", "multipliers_after": the point's in the old and in the new coordinates}
    reanchors: list[dict] = field(default_factory=list)


class _Failure(Exception):
    """A point could not be computed (no convergence, non-finite values, an error of a callable)."""


class _Contract(NsfemError):
    """A callable broke its contract (shapes, types): a programming error, never retried."""


@dataclass
class _Point:
    z: np.ndarray
    jac: np.ndarray          # (m, m+1) scaled [J_u u_scale | J_p (p_end - p0)] at z
    rmax: float
    iterations: int
    multipliers: np.ndarray | None = None
    structure: object = None     # the solution's non-smooth structure (``events``): None without it
    margin: float = math.inf     # its distance to the nearest change of structure (0 at a grazing)
    invariant: np.ndarray | None = None   # coordinate-free measures of the solution (``invariant``)


def _line(exc: Exception) -> str:
    """An error's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _finite_float(name: str, value, *, positive: bool = False, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise NsfemError(f"continue_branch: {name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or (positive and x <= 0):
        raise NsfemError(f"continue_branch: {name} must be a finite number{' > 0' if positive else ''}, got {x!r}")
    return x


class _Scaled:
    """The residual and the stability in scaled unknowns z = (u / u_scale, (p - p0) / (p_end - p0))."""

    def __init__(self, residual: Residual, stability: Stability | None, m: int, u_scale: np.ndarray,
                 p0: float, p_end: float, events: Callable | None = None, invariant: Callable | None = None,
                 solve: Callable | None = None):
        self.residual, self.stability, self.m = residual, stability, m
        self.events, self.invariant, self.solve = events, invariant, solve
        self.u_scale, self.p0, self.p_end, self.span = u_scale, p0, p_end, p_end - p0
        self._last: tuple[bytes, tuple[np.ndarray, np.ndarray]] | None = None

    def z(self, u: np.ndarray, p: float) -> np.ndarray:
        return np.append(np.asarray(u, float) / self.u_scale, (p - self.p0) / self.span)

    def u(self, z: np.ndarray) -> np.ndarray:
        return z[:-1] * self.u_scale

    def p(self, z: np.ndarray) -> float:
        return self.p_end if z[-1] == 1.0 else float(self.p0 + z[-1] * self.span)

    def evaluate(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r (m,) and the scaled Jacobian (m, m+1) at z; _Failure when not finite or the residual fails.
        The last evaluation is kept: asked again at the same z, the residual is not called again."""
        key = z.tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        u, p = self.u(z), self.p(z)
        try:
            out = self.residual(u.copy(), p)
        except _Contract:
            raise
        except (NsfemError, ArithmeticError, np.linalg.LinAlgError) as exc:
            raise _Failure(f"the residual failed at p = {p:.10g}: {_line(exc)}") from exc
        if not isinstance(out, tuple) or len(out) != 3:
            raise _Contract("continue_branch: residual(u, p) must return a tuple (r, J_u, J_p), got "
                            f"{type(out).__name__}")
        m = self.m
        try:
            if any(np.iscomplexobj(a) for a in out):
                raise TypeError("complex values")
            r, ju, jp = (np.asarray(a, dtype=float) for a in out)
        except (TypeError, ValueError) as exc:
            raise _Contract(f"continue_branch: residual(u, p) must return real arrays (r, J_u, J_p): "
                            f"{_line(exc)}") from None
        for name, a, shape in (("r", r, (m,)), ("J_u", ju, (m, m)), ("J_p", jp, (m,))):
            if a.shape != shape:
                raise _Contract(f"continue_branch: residual(u, p) returned {name} of shape {a.shape}, expected "
                                f"{shape} for {m} unknowns")
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(ju)) and np.all(np.isfinite(jp))):
            raise _Failure(f"the residual or its Jacobian is not finite at p = {p:.10g}")
        jac = np.empty((m, m + 1))
        jac[:, :m] = ju * self.u_scale
        jac[:, m] = jp * self.span
        self._last = (key, (r, jac))
        return r, jac

    def multipliers(self, z: np.ndarray) -> np.ndarray | None:
        """The stability's multipliers at z, sorted by modulus (largest first); None without stability."""
        if self.stability is None:
            return None
        p = self.p(z)
        try:
            mu = self.stability(self.u(z).copy(), p)
        except _Contract:
            raise
        except (NsfemError, ArithmeticError, np.linalg.LinAlgError) as exc:
            raise _Failure(f"the stability failed at p = {p:.10g}: {_line(exc)}") from exc
        try:
            mu = np.asarray(mu, dtype=complex)
        except (TypeError, ValueError):
            raise _Contract("continue_branch: stability(u, p) must return an array of multipliers") from None
        if mu.ndim != 1:
            raise _Contract(f"continue_branch: stability(u, p) must return a 1-D array of multipliers, got shape "
                            f"{mu.shape}")
        if not np.all(np.isfinite(mu)):
            raise _Failure(f"the multipliers are not finite at p = {p:.10g}")
        return mu[np.argsort(-np.abs(mu), kind="stable")]

    def solved(self, z: np.ndarray, level: float) -> np.ndarray | None:
        """The caller's ``solve`` from u(z) at the parameter of z_p = level, in scaled unknowns; None without it or
        when it finds nothing."""
        if self.solve is None:
            return None
        p = self.p_end if level == 1.0 else float(self.p0 + level * self.span)
        try:
            u = self.solve(self.u(z).copy(), p)
        except _Contract:
            raise
        except (NsfemError, ArithmeticError, np.linalg.LinAlgError):
            return None
        if u is None:
            return None
        u = np.asarray(u, dtype=float)
        if u.shape != (self.m,):
            raise _Contract(f"continue_branch: solve(u, p) must return None or an array of shape ({self.m},), got "
                            f"{u.shape}")
        return self.z(u, p) if np.all(np.isfinite(u)) else None

    def structure(self, pt: _Point):
        """The structure (``events``) of the corrected point pt: pt's own when known, else asked; None without
        ``events`` or when they fail."""
        if self.events is None:
            return None
        if pt.structure is not None:
            return pt.structure
        try:
            return self.events(self.u(pt.z).copy(), self.p(pt.z))[0]
        except (NsfemError, ArithmeticError, np.linalg.LinAlgError, TypeError, ValueError):
            return None

    def complete(self, pt: _Point) -> _Point:
        """pt with its multipliers, its structure and margin (``events``) and its invariant, all at pt.z (where the
        residual was just evaluated)."""
        pt.multipliers = self.multipliers(pt.z)
        p, u = self.p(pt.z), self.u(pt.z)
        if self.events is not None:
            try:
                out = self.events(u.copy(), p)
            except _Contract:
                raise
            except (NsfemError, ArithmeticError, np.linalg.LinAlgError) as exc:
                raise _Failure(f"the events failed at p = {p:.10g}: {_line(exc)}") from exc
            try:
                structure, margin = out
                hash(structure)
                margin = float(margin)
            except (TypeError, ValueError):
                raise _Contract("continue_branch: events(u, p) must return (a hashable structure, a margin >= 0)") \
                    from None
            if not margin >= 0.0:
                raise _Failure(f"the margin to a change of structure is {margin!r} at p = {p:.10g} (must be >= 0)")
            pt.structure, pt.margin = structure, margin
        if self.invariant is not None:
            try:
                inv = np.atleast_1d(np.asarray(self.invariant(u.copy(), p), dtype=float))
            except _Contract:
                raise
            except (NsfemError, ArithmeticError, np.linalg.LinAlgError) as exc:
                raise _Failure(f"the invariant failed at p = {p:.10g}: {_line(exc)}") from exc
            except (TypeError, ValueError):
                raise _Contract("continue_branch: invariant(u, p) must return an array of numbers") from None
            if inv.ndim != 1 or not np.all(np.isfinite(inv)):
                raise _Failure(f"the invariant is not a finite 1-D array at p = {p:.10g}")
            pt.invariant = inv
        return pt


def _tangent(jac: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Unit null vector of jac (m, m+1), oriented so that t . previous > 0 (Keller's bordered system;
    the smallest right singular vector where the bordered matrix is singular)."""
    m = jac.shape[0]
    rhs = np.zeros(m + 1)
    rhs[m] = 1.0
    t = None
    try:
        t = np.linalg.solve(np.vstack([jac, previous]), rhs)
    except np.linalg.LinAlgError:
        pass
    if t is None or not np.all(np.isfinite(t)) or np.linalg.norm(t) == 0:
        t = np.linalg.svd(jac)[2][-1]
    t = t / np.linalg.norm(t)
    return -t if t @ previous < 0 else t


def _correct(problem: _Scaled, z0: np.ndarray, row: np.ndarray, level: float, tol: float,
             max_iter: int) -> _Point:
    """Newton on [r(z); row.z - level] = 0 from z0 (the bordered system); _Failure if it does not
    reach max |r| <= tol in max_iter steps."""
    z = z0.copy()
    fixed_p = not np.any(row[:-1])    # a constraint on p alone: held exactly, not to round-off
    first = None
    for k in range(max_iter + 1):
        r, jac = problem.evaluate(z)
        rmax = float(np.max(np.abs(r))) if r.size else 0.0
        if rmax <= tol:
            return _Point(z, jac, rmax, k)
        first = rmax if first is None else first
        if k == max_iter or rmax > 1e6 * max(first, tol):
            break
        try:
            dz = np.linalg.solve(np.vstack([jac, row]), -np.append(r, row @ z - level))
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(dz)):
            break
        z = z + dz
        if fixed_p:
            z[-1] = level / row[-1]
    raise _Failure(f"the corrector did not converge at p = {problem.p(z):.10g} (max |r| = {rmax:.3g} > tol = "
                   f"{tol:.3g} after {k} Newton steps)")


def _outside(mu: np.ndarray, unit_tol: float) -> np.ndarray:
    return np.abs(mu) > 1.0 + unit_tol


def _kind(mu: complex) -> str:
    if abs(mu.imag) > REAL_TOL * max(1.0, abs(mu)):
        return "neimark-sacker"
    return "fold" if mu.real > 0 else "period-doubling"


def _padded(mu: np.ndarray, n: int) -> np.ndarray:
    """mu with zeros appended up to n: a direction that is held at one point and free at another (an
    orbit's contact held closed on its section) has multiplier 0 where it is held."""
    return np.pad(mu, (0, max(0, n - mu.size)))


def _paired(ma: np.ndarray, mb: np.ndarray) -> np.ndarray:
    """For each multiplier of ma, the index of its partner in mb (same length): the pairs of least
    sum of sqrt(distance). The concave cost prefers one large move and the others unchanged to several
    moderate ones: where a held direction is freed (0 -> mu, the others continuous) it pairs the 0 with
    the new mu (a plain sum of distances ties there: 0.5 -> 0.5, 0 -> 1.5 costs 1.5 as 0.5 -> 1.5, 0 -> 0.5)."""
    rows, cols = linear_sum_assignment(np.sqrt(np.abs(ma[:, None] - mb[None, :])))
    partner = np.empty(ma.size, dtype=int)
    partner[rows] = cols
    return partner


def _crossings(ma: np.ndarray, mb: np.ndarray, unit_tol: float) -> list[tuple[int, int]]:
    """Index pairs (at A, at B) of the multipliers (of equal length) that changed side of the unit
    circle; one of each complex-conjugate pair (the one with Im >= 0 at B)."""
    partner = _paired(ma, mb)
    out_a, out_b = _outside(ma, unit_tol), _outside(mb, unit_tol)
    pairs = [(i, int(partner[i])) for i in range(ma.size) if out_a[i] != out_b[partner[i]]]
    kept = []
    for i, j in pairs:
        b = complex(mb[j])
        conjugate = any(abs(b.conjugate() - mb[j2]) <= 1e-9 * max(1.0, abs(b)) and mb[j2].imag > 0
                        for _, j2 in pairs)
        if not (b.imag < 0 and conjugate):
            kept.append((i, j))
    return kept


def _outside_counts(mu: np.ndarray, unit_tol: float) -> dict:
    """The number of multipliers outside the unit circle by kind (real > 0, real < 0, complex)."""
    counts = {"fold": 0, "period-doubling": 0, "neimark-sacker": 0}
    for m in mu[_outside(mu, unit_tol)]:
        counts[_kind(complex(m))] += 1
    return counts


def _side_changes(samples: list, n: int, unit_tol: float) -> list[tuple]:
    """The multipliers followed through ``samples`` [(theta, point, multipliers)] by pairing neighbours: each
    change of side of the unit circle (k: between samples k and k + 1, index at k, index at k + 1); one of each
    complex-conjugate pair (the one with Im >= 0 after)."""
    found = []
    for i in range(n):
        idx = i
        for k, ((_, _, m1), (_, _, m2)) in enumerate(zip(samples, samples[1:])):
            j = int(_paired(m1, m2)[idx])
            if _outside(m1[idx:idx + 1], unit_tol)[0] != _outside(m2[j:j + 1], unit_tol)[0]:
                b = complex(m2[j])
                conjugate = np.any((np.abs(b.conjugate() - m2) <= 1e-9 * max(1.0, abs(b))) & (m2.imag > 0))
                if not (b.imag < 0 and conjugate):
                    found.append((k, idx, j))
            idx = j
    return found


def _resolved(m1: np.ndarray, i: int, m2: np.ndarray, j: int) -> bool:
    """Whether the pairing of m1[i] with m2[j] is unambiguous: the move is under RESOLVED of its distance to every
    other multiplier, at both ends (a crossing seen through it is then the multiplier's own, not an exchange)."""
    move = abs(m1[i] - m2[j])
    for m, k in ((m1, i), (m2, j)):
        others = np.delete(m, k)
        if others.size and move >= RESOLVED * np.abs(others - m[k]).min():
            return False
    return True


def _straddles(m1: np.ndarray, m2: np.ndarray, unit_tol: float) -> bool:
    """Whether a multiplier's pairing across the stretch (m1 -> m2) is ambiguous with one on the other side of the
    unit circle: within four times its move of it (:data:`RESOLVED`) at either end. Two such multipliers may have
    exchanged places, one going out and one coming in, which the ends' pairing sees as no crossing at all."""
    partner = _paired(m1, m2)
    out1, out2 = _outside(m1, unit_tol), _outside(m2, unit_tol)
    for i in range(m1.size):
        j = int(partner[i])
        reach = abs(m1[i] - m2[j]) / RESOLVED
        if reach > 0 and (np.any((np.abs(m1 - m1[i]) <= reach) & (out1 != out1[i]))
                          or np.any((np.abs(m2 - m2[j]) <= reach) & (out2 != out2[j]))):
            return True
    return False


def _followed_crossings(chord: "_Chord", ma: np.ndarray, mb: np.ndarray, n: int, unit_tol: float,
                        min_length_z: float, budget: int = MAX_FOLLOW) -> list[tuple] | None:
    """The crossings of the unit circle between A and B, each (theta_lo, theta_hi, point_lo, point_hi, index at
    lo, index at hi). Pairing A's multipliers with B's claims a crossing wherever a multiplier changed side, which
    is wrong where two on different sides passed near each other (a spurious pair of crossings). Each claimed
    crossing is followed: its stretch of the chord halved (a trial point with its multipliers; at least once)
    until the pairing across it is unambiguous (:func:`_resolved`); claims that vanish on the way were exchanges.
    None when a claim
    stays ambiguous down to ``min_length_z`` or ``budget`` trial points, or a trial point fails."""
    samples = [(0.0, chord.a, ma), (1.0, chord.b, mb)]
    used = 0
    while True:
        changes = _side_changes(samples, n, unit_tol)
        # (a claim over the whole step is always checked by one trial point at least: an exchange of two
        # multipliers passing each other may look like a short move of each)
        open_ = sorted({k for k, i, j in changes if len(samples) == 2
                        or not _resolved(samples[k][2], i, samples[k + 1][2], j)}, reverse=True)
        if not open_ and len(samples) == 2 and _straddles(ma, mb, unit_tol):
            open_ = [0]   # (no claim, yet two multipliers on either side may have swapped: one trial point)
        if not open_:
            return [(samples[k][0], samples[k + 1][0], samples[k][1], samples[k + 1][1], i, j)
                    for k, i, j in changes]
        for k in open_:   # (from the end: the indices of the earlier stretches stay)
            (t1, _, _), (t2, _, _) = samples[k], samples[k + 1]
            if (t2 - t1) * chord.length <= min_length_z or used >= budget:
                return None
            theta = 0.5 * (t1 + t2)
            try:
                pt = chord.point(theta, True)
            except _Failure:
                return None
            used += 1
            samples.insert(k + 1, (theta, pt, _padded(pt.multipliers, n)))


class _Chord:
    """Trial points between two branch points A and B (tangents ta, tb), re-corrected onto the branch in
    the hyperplane across the chord at theta. Newton starts from the cubic Hermite curve through A and B
    with their tangents (its offset from the chord, across it; on the chord itself where a tangent is
    nearly across the chord): one or two Newton steps fewer than from the chord on a curved branch."""

    def __init__(self, problem: _Scaled, a: _Point, ta: np.ndarray, b: _Point, tb: np.ndarray, tol: float,
                 max_iter: int):
        self.problem, self.a, self.b, self.tol, self.max_iter = problem, a, b, tol, max_iter
        self.bracket = (a, b)    # (the last located sign change's final bracket: :func:`_locate`)
        chord = b.z - a.z
        self.length = float(np.linalg.norm(chord))
        self.d = chord / self.length if self.length > 0 else chord
        slopes = []     # d(offset)/d(distance along the chord) at A and B
        for t in (ta, tb):
            along = float(t @ self.d)
            slopes.append((t - along * self.d) / along if along > 0.5 else np.zeros_like(t))
        self.slopes = slopes

    def point(self, theta: float, with_multipliers: bool) -> _Point:
        zt = self.a.z + theta * (self.b.z - self.a.z)
        guess = zt + self.length * ((theta ** 3 - 2 * theta ** 2 + theta) * self.slopes[0]
                                    + (theta ** 3 - theta ** 2) * self.slopes[1])
        pt = _correct(self.problem, guess, self.d, float(self.d @ zt), self.tol, self.max_iter)
        if with_multipliers:
            pt.multipliers = self.problem.multipliers(pt.z)
        return pt


def _locate(chord: _Chord, g: Callable[[_Point, float], float], g_a: float, g_b: float, span_tol: float,
            with_multipliers: bool, bracket: tuple | None = None) -> tuple[_Point, float, float]:
    """The sign change of g along the chord (g(A) = g_a and g(B) = g_b of opposite signs), bracketed until
    the bracket's chord is at most span_tol: (the bracket's end with the smaller |g|, its theta, its
    distance in scaled z to the other end; the crossing lies on the branch between them).

    Regula falsi with the Illinois modification (the end kept twice has its g halved) converges
    superlinearly on a smooth g; a step that leaves the bracket more than half its width of two steps
    before is followed by a bisection, so the bracket at least halves every three steps (a test
    function with a jump, as a multiplier appearing, is located by bisection then). A trial point within
    span_tol / 2 of an end is moved to span_tol / 2 from it, so that a crossing next to an end is closed
    in by a bracket of width span_tol rather than approached from one side. The final bracket's ends are left in
    ``chord.bracket``."""
    lo, hi, glo, ghi = 0.0, 1.0, g_a, g_b
    pt_lo, pt_hi = chord.a, chord.b
    if bracket is not None:     # a narrower start (lo, hi, its points), found by following the multipliers
        lo, hi, pt_lo, pt_hi = bracket
    kept, widths = 0, [math.inf, math.inf]
    half_tol = 0.5 * span_tol / chord.length
    chord.bracket = (pt_lo, pt_hi)
    if (g_a > 0) == (g_b > 0):     # no sign change to follow: the nearer end, to the bracket's length
        width = float(np.linalg.norm(pt_hi.z - pt_lo.z))
        return (pt_lo, lo, width) if abs(g_a) <= abs(g_b) else (pt_hi, hi, width)
    for _ in range(MAX_TRIALS):
        width = hi - lo
        if width * chord.length <= span_tol:
            break
        if width > 0.5 * widths[-2]:
            theta = 0.5 * (lo + hi)
        else:
            theta = lo - glo * width / (ghi - glo)
            theta = min(max(theta, lo + min(half_tol, 0.25 * width)), hi - min(half_tol, 0.25 * width))
        widths.append(width)
        try:
            pt = chord.point(theta, with_multipliers)
            val = g(pt, theta)
        except _Failure:
            break
        if val == 0.0:
            chord.bracket = (pt, pt)
            return pt, theta, 0.0
        if (val > 0) == (glo > 0):
            lo, glo, pt_lo = theta, val, pt
            ghi, kept = (0.5 * ghi, kept) if kept == 1 else (ghi, 1)
        else:
            hi, ghi, pt_hi = theta, val, pt
            glo, kept = (0.5 * glo, kept) if kept == -1 else (glo, -1)
    chord.bracket = (pt_lo, pt_hi)
    if abs(glo) <= abs(ghi):
        return pt_lo, lo, float(np.linalg.norm(pt_hi.z - pt_lo.z))
    return pt_hi, hi, float(np.linalg.norm(pt_hi.z - pt_lo.z))


def _special_points(problem: _Scaled, a: _Point, ta: np.ndarray, b: _Point, tb: np.ndarray, index: int,
                    tol: float, max_iter: int, locate_tol_z: float, unit_tol: float) -> list[dict]:
    """The folds and stability changes between consecutive points a and b, located."""
    chord = _Chord(problem, a, ta, b, tb, tol, max_iter)
    if chord.length == 0:
        return []
    found: list[tuple[float, dict]] = []
    scale = abs(problem.span)

    def record(kind: str, pt: _Point, theta: float, half: float, how: str) -> None:
        found.append((theta, {"kind": kind, "value": problem.p(pt.z), "index": index, "u": problem.u(pt.z),
                              "multipliers": pt.multipliers, "accuracy": half * scale, "detected_by": how}))

    with_mu = a.multipliers is not None
    # a step over a change of structure (``events``): a multiplier that jumps across the unit circle at the grazing
    # is no smooth crossing (its located bracket straddles the change; the located grazing is not searched either)
    kinked = a.structure is not None and b.structure is not None and a.structure != b.structure
    fold_by_tangent = ta[-1] * tb[-1] < 0
    if fold_by_tangent:
        # tangents re-oriented by the chord, so that the sign of t_p means the same at every trial point
        def tp(pt: _Point, _theta: float) -> float:
            return float(_tangent(pt.jac, chord.d)[-1])

        pt, theta, half = _locate(chord, tp, tp(a, 0.0), tp(b, 1.0), locate_tol_z, with_mu)
        record("fold", pt, theta, half, "tangent")
    if with_mu:
        n = max(a.multipliers.size, b.multipliers.size)
        ma, mb = _padded(a.multipliers, n), _padded(b.multipliers, n)
        # the multipliers followed from A to B with trial points added where pairing A's with B's could exchange
        # multipliers on different sides of the circle passing near each other (a spurious pair of crossings, or
        # two real ones hidden): none added where it cannot
        crossings = _followed_crossings(chord, ma, mb, n, unit_tol, locate_tol_z)
        if crossings is None:    # still ambiguous: a crossing is real only where the count outside changed
            same = _outside_counts(ma, unit_tol) == _outside_counts(mb, unit_tol)
            crossings = [] if same else [(0.0, 1.0, a, b, i, j) for i, j in _crossings(ma, mb, unit_tol)]
        for lo, hi, pt_lo, pt_hi, i, j in crossings:
            # the crossing multiplier followed by pairing each trial's multipliers with those of the
            # nearest point known: theta -> (multipliers, the index of the followed one)
            track = {lo: (_padded(pt_lo.multipliers, n), i), hi: (_padded(pt_hi.multipliers, n), j)}

            def followed(pt: _Point, theta: float) -> complex:
                mu_ref, k = track[min(track, key=lambda key: abs(key - theta))]
                mu = _padded(pt.multipliers, n)
                k = int(_paired(mu_ref, mu)[k])
                track[theta] = (mu, k)
                return complex(mu[k])

            mu_a, mu_b = complex(track[lo][0][i]), complex(track[hi][0][j])
            g_a, g_b = abs(mu_a) - 1.0, abs(mu_b) - 1.0
            if g_a * g_b > 0:     # the inside end lies within unit_tol outside the circle: the crossing is
                # there, or just beyond it by the linear extrapolation of |mu| - 1 (its accuracy)
                inside_a = not _outside(np.array([mu_a]), unit_tol)[0]
                pt, theta, mu = (pt_lo, lo, mu_a) if inside_a else (pt_hi, hi, mu_b)
                half = abs(g_a if inside_a else g_b) / abs(g_b - g_a) * float(np.linalg.norm(pt_hi.z - pt_lo.z))
            else:
                pt, theta, half = _locate(chord, lambda pt, theta: abs(followed(pt, theta)) - 1.0, g_a, g_b,
                                          locate_tol_z, True, (lo, hi, pt_lo, pt_hi))
                if kinked:
                    ends = [problem.structure(end) for end in chord.bracket]
                    if None not in ends and ends[0] != ends[1]:
                        continue   # (the multiplier jumps at the grazing within the step: the grazing's)
                mu = followed(pt, theta)
            kind = _kind(mu)
            if kind == "fold" and fold_by_tangent:
                continue          # a saddle-node: recorded once, as the branch's fold
            record(kind, pt, theta, half, "multipliers")
    return [d for _, d in sorted(found, key=lambda x: x[0])]


def _graze_point(problem: _Scaled, start: _Point, direction: np.ndarray, past: float | None, tol: float,
                 max_iter: int, locate_z: float, before: _Point | None = None, first: float | None = None
                 ) -> tuple[_Point, float] | None:
    """The point of ``start``'s side of the branch where its margin (``events``) reaches 0: a grazing point.

    Trial points lie on the branch in the hyperplanes direction.(z - start.z) = sigma (``direction`` a unit vector
    along the branch, towards the grazing), each corrected there and kept when it has start's structure; one
    corrected with another structure lies past the grazing and bounds it (as ``past`` does: a sigma known to lie
    past it); one whose correction fails bounds only the next trial (next to a grazing an impacting orbit's Newton
    basin shrinks with its approach speed: Nordmark's square-root map). The margin is smooth on one side of a
    grazing (an open gap's minimum, an impact's approach speed: linear in the distance), so the secant through the
    last two kept points converges superlinearly from that side; a secant that leaves the bracket is replaced by
    bisection. The first trial is at ``first``, or, with ``before`` (a point of the same side behind start), the
    secant's. Returns (the kept point of least margin, the accuracy in z: the distance from it to the zero the
    secant predicts, or to ``past``, whichever is less) once that accuracy is below ``locate_z``, else as far as
    MAX_GRAZE_TRIALS trial points (or GRAZE_FAILS failed ones in a row) allow; None when none was kept."""
    level0 = float(direction @ start.z)
    goods = [(0.0, start)]
    if before is not None and before.structure == start.structure and math.isfinite(before.margin):
        sb = float(direction @ before.z) - level0
        if sb < 0.0:
            goods.insert(0, (sb, before))
    limit, fails = past, 0

    def accuracy() -> float:
        """The kept points' distance to the grazing: the secant's through the last two (where the margin fell
        between them), or to ``past``."""
        (s1, p1), (s2, p2) = goods[-2] if len(goods) > 1 else (None, None), goods[-1]
        out = math.inf if past is None else past - s2
        if s1 is not None and p1.margin > p2.margin:
            out = min(out, p2.margin * (s2 - s1) / (p1.margin - p2.margin))
        return out

    for _ in range(MAX_GRAZE_TRIALS):
        (s2, p2) = goods[-1]
        if p2.margin == 0.0:
            return p2, 0.0
        if accuracy() <= locate_z:
            break
        if len(goods) > 1 and goods[-2][1].margin <= p2.margin:
            break     # (the margin no longer falls: its noise, the corrector's tolerance, is reached)
        # a little short of the secant's zero (GRAZE_AIM of the way): the next kept point is again on this side
        sigma = s2 + GRAZE_AIM * accuracy() if len(goods) > 1 else first
        if limit is not None and (sigma is None or not s2 < sigma < limit):
            sigma = 0.5 * (s2 + limit)
        if sigma is None or fails >= GRAZE_FAILS:
            break
        if len(goods) > 1:
            s1, p1 = goods[-2]
            z_pred = p2.z + (sigma - s2) * (p2.z - p1.z) / (s2 - s1)
        else:
            z_pred = p2.z + (sigma - s2) * direction
        try:
            pt = problem.complete(_correct(problem, z_pred, direction, level0 + sigma, tol, max_iter))
        except _Failure:
            pt = None
        if pt is not None and pt.structure == start.structure:
            goods.append((sigma, pt))
        else:
            if pt is not None:    # corrected with another structure: past the grazing
                past = sigma if past is None else min(past, sigma)
            fails += 1
            limit = sigma if limit is None else min(limit, sigma)
    return (goods[-1][1], accuracy()) if len(goods) > 1 or past is not None else None


def _beyond(problem: _Scaled, g: _Point, t: np.ndarray, structure, steps: list[float], tol: float,
            max_iter: int) -> _Point | None:
    """A point of the branch past the grazing point g with another structure than ``structure`` (the side the
    branch came from): corrected at a fixed parameter p(g) + h (natural parameter), h from ``steps`` (scaled p),
    in the direction the branch went (the sign of t's p component; against it too where t is at a fold in p);
    started from g, from g extrapolated along t and by the caller's ``solve``. None when no such point is found."""
    e_p = np.zeros(g.z.size)
    e_p[-1] = 1.0
    sign = 1.0 if t[-1] >= 0 else -1.0
    # (against the branch's direction only where it is at a fold in p: elsewhere a point there of another structure
    # is no continuation of this branch; it may be another branch through the same grazing, or the way back)
    for direction in ((sign, -sign) if abs(t[-1]) < FOLD_TP else (sign,)):
        far = math.inf   # (a point of the other structure found at h and not joined to g: an arm of it past a fold
        # next to the grazing reaches to h already, so a larger h finds that arm again, never the continuation)
        for h in steps:
            if h >= far:
                continue
            level = g.z[-1] + direction * h
            along = t * (direction * h / t[-1]) if abs(t[-1]) > FOLD_TP else np.zeros_like(t)
            for k, z_pred in enumerate((np.append(g.z[:-1], level), g.z + along, None)):
                try:
                    if z_pred is None:   # the caller's own solver from g (an orbit's shooting: damped, patient)
                        z_pred = problem.solved(g.z, level)
                        if z_pred is None:
                            continue
                    z_pred = z_pred.copy()
                    z_pred[-1] = level
                    pt = problem.complete(_correct(problem, z_pred, e_p, level, tol, max_iter))
                except _Failure:
                    continue
                if pt.structure != structure:
                    pt = _nearer(problem, g, pt, e_p, structure, tol, max_iter)
                    if _joins(g, pt):
                        return pt
                    far = min(far, h)
                    break
    return None


def _kink_joins(a: _Point, ta: np.ndarray, b: _Point, tb: np.ndarray, before: _Point | None = None) -> bool:
    """Whether a step from a to b over a change of structure passes a kink of one branch: a's tangent line ahead of a
    and b's behind b meet (their nearest points a + s ta, b - r tb with s, r >= 0, apart by at most half the shorter
    way, min(s, r); a kink between two straight pieces: exactly, up to the corrector's error, hence the chord's 1e-6;
    curved sides: to second order in the way). b on another arm of its structure, past a fold of that side next to
    the grazing (the fold skipped), has its line cross a's behind a or ahead of b, or pass it at that arm's distance,
    or (a square-root arm: its line meets a's at c - y^2 where the grazing is at c) far short of where a's margin,
    falling from ``before``'s as it did, reaches 0."""
    chord = b.z - a.z
    length = float(np.linalg.norm(chord))
    if length == 0.0:
        return True
    (s, r), *_ = np.linalg.lstsq(np.column_stack([ta, tb]), chord, rcond=1e-12)
    miss = float(np.linalg.norm(chord - s * ta - r * tb))
    slack = 0.5 * min(s, r) + 1e-6 * length
    if not (s >= 0.0 and r >= 0.0 and miss <= slack):
        return False
    # and, turned by more than 10 degrees (a far arm near its fold is steep), not far short of where a's margin,
    # falling as it did from ``before``, reaches 0 (an orbit's margin is a least over its contacts and events, linear
    # only piecewise, capped: within a factor SHORT_OF_ZERO; the crack's small turns over changes of its events pass)
    if ta @ tb > EASY_TURN_COS or before is None or before.structure != a.structure or not math.isfinite(before.margin):
        return True
    run = float(ta @ (a.z - before.z))
    if run <= 0.0 or before.margin <= a.margin:
        return True
    return bool(s >= SHORT_OF_ZERO * a.margin * run / (before.margin - a.margin))


def _joins(g: _Point, b: _Point) -> bool:
    """Whether b's side of the branch, followed back along b's own tangent to the parameter of the grazing point g,
    ends within half of b's distance from g: b continues the branch through g (on a square-root side the miss is
    O(distance^2)), rather than lying on a far arm of the other structure past a fold next to the grazing (which
    misses g by that arm's distance from it, whatever the parameter's). A tangent at a fold in p cannot tell: no."""
    d = g.z - b.z
    dist = float(np.linalg.norm(d))
    if dist == 0.0:
        return True
    tb = _tangent(b.jac, d / dist)
    if abs(tb[-1]) <= FOLD_TP:
        return False
    back = b.z + tb * (d[-1] / tb[-1])
    return bool(np.linalg.norm(back - g.z) <= 0.5 * dist)


def _nearer(problem: _Scaled, g: _Point, b: _Point, e_p: np.ndarray, structure, tol: float, max_iter: int) -> _Point:
    """The point of b's side nearest the grazing point g among p(g) + (p(b) - p(g)) / 2^k, k = 1..NEARER, each
    corrected at its p from the last one along its side's tangent (the way back along b's side, to where its
    corrector fails): the branch then has no long chord past the grazing."""
    for _ in range(NEARER):
        level = 0.5 * (g.z[-1] + b.z[-1])
        tb = _tangent(b.jac, (g.z - b.z) / max(float(np.linalg.norm(g.z - b.z)), 1e-300))
        z_pred = b.z + tb * ((level - b.z[-1]) / tb[-1]) if abs(tb[-1]) > FOLD_TP else b.z + 0.5 * (g.z - b.z)
        z_pred[-1] = level
        try:
            pt = problem.complete(_correct(problem, z_pred, e_p, level, tol, max_iter))
        except _Failure:
            break
        if pt.structure == structure:
            break
        b = pt
    return b


def _returned(a: _Point, b: _Point, first_z: np.ndarray | None, first: _Point, excursion: float = 0.0) -> bool:
    """Whether the chord from a to b passes the branch's first point (within a quarter of its length): in the
    unknowns when they are in the first point's coordinates (``first_z``), else in the coordinate-free measures
    (``invariant``, over ``excursion``: their largest distance from the first point's along the branch so far; and
    z_p), when the caller gives them. (Over the invariant's own size instead, a large constant part, as an orbit's mean
    under a static load, made other solutions at the first point's parameter, a fold's other segments, look like it.)"""
    if first_z is not None:
        za, zb, z1 = a.z, b.z, first_z
    elif first.invariant is not None and a.invariant is not None and b.invariant is not None:
        size = max(excursion, 1e-300)
        za, zb, z1 = (np.append(pt.invariant / size, pt.z[-1]) for pt in (a, b, first))
    else:
        return False
    w = zb - za
    length = float(np.linalg.norm(w))
    if length == 0.0:
        return False
    x = float(np.clip((z1 - za) @ w / (w @ w), 0.0, 1.0))
    return bool(np.linalg.norm(za + x * w - z1) < 0.25 * length)


def _grazing_ahead(a: _Point, before: _Point | None, t: np.ndarray, ds: float) -> bool:
    """Whether the grazing of a's side may lie within a step of ``ds`` from a: its margin is small (below
    NEAR_MARGIN), or falling so fast along the branch that it reaches 0 within GRAZE_REACH such steps."""
    if a.structure is None or not math.isfinite(a.margin):
        return False
    if a.margin <= NEAR_MARGIN:
        return True
    if before is None or before.structure != a.structure or not math.isfinite(before.margin):
        return False
    run = float(t @ (a.z - before.z))
    if run <= 0.0 or before.margin <= a.margin:
        return False
    return a.margin / ((before.margin - a.margin) / run) <= GRAZE_REACH * ds


def _branch_point(problem: _Scaled, pt: _Point, s: float, tol: float, unit_tol: float, anchor: int = 0
                  ) -> BranchPoint:
    mu = pt.multipliers
    stable = None if mu is None else bool(np.all(np.abs(mu) < 1.0 + unit_tol))
    return BranchPoint(p=problem.p(pt.z), u=problem.u(pt.z), multipliers=mu, stable=stable,
                       converged=pt.rmax <= tol, residual=pt.rmax, s=s, anchor=anchor)


def _reanchored(problem: _Scaled, reanchor: Callable, pt: _Point, t: np.ndarray, forced: bool, tol: float,
                max_iter: int) -> tuple[_Point, np.ndarray] | None:
    """The point in the coordinates ``reanchor`` moves to (re-corrected there at its p) and its tangent, oriented
    as the old one mapped by the change's Jacobian (by the sign of its p component without one); None when
    ``reanchor`` keeps the coordinates. _Failure when the change or the re-correction fails."""
    u, p = problem.u(pt.z), problem.p(pt.z)
    try:
        out = reanchor(u.copy(), p, forced)
    except _Contract:
        raise
    except (NsfemError, ArithmeticError, np.linalg.LinAlgError) as exc:
        raise _Failure(f"moving the coordinates at p = {p:.10g} failed: {_line(exc)}") from exc
    if out is None:
        return None
    try:
        out = tuple(out)
        if len(out) not in (2, 3):
            raise ValueError
        u_new, M, dudp = out if len(out) == 3 else (*out, None)
        u_new = np.asarray(u_new, dtype=float)
        M = None if M is None else np.asarray(M, dtype=float)
        dudp = None if dudp is None else np.asarray(dudp, dtype=float)
    except (TypeError, ValueError):
        raise _Contract("continue_branch: reanchor(u, p, forced) must return None or (u_new, M or None) or (u_new, "
                        "M or None, du_new/dp or None)") from None
    m = problem.m
    if u_new.shape != (m,) or (M is not None and M.shape != (m, m)) or (dudp is not None and dudp.shape != (m,)):
        raise _Contract(f"continue_branch: reanchor returned u of shape {u_new.shape} and M of shape "
                        f"{None if M is None else M.shape}"
                        + ("" if dudp is None else f" and du_new/dp of shape {dudp.shape}")
                        + f", expected ({m},) and ({m}, {m})" + ("" if dudp is None else f" and ({m},)"))
    if not (np.all(np.isfinite(u_new)) and (M is None or np.all(np.isfinite(M)))
            and (dudp is None or np.all(np.isfinite(dudp)))):
        raise _Failure(f"moving the coordinates at p = {p:.10g} gave values that are not finite")
    problem._last = None     # (the residual is another function of u now)
    z = problem.z(u_new, p)
    z[-1] = pt.z[-1]
    e_p = np.zeros(m + 1)
    e_p[-1] = 1.0
    new = _correct(problem, z, e_p, float(z[-1]), tol, max_iter)
    problem.complete(new)
    # the old tangent in the new coordinates: du_new/ds = M du/ds + du_new/dp dp/ds (the new state depends on p
    # at a fixed old one too: an orbit's flow over the section's shift does). Without du_new/dp, M du/ds alone can
    # point against the branch (it turned back: test_a_move_whose_state_depends_on_p_keeps_the_branchs_direction);
    # the sign of dp/ds is the same in any coordinates, so it orients the tangent, except near a fold of the branch
    # (|t_p| below FOLD_TP), where the term left out is as small as t_p and M du/ds orients it
    if M is not None and dudp is not None:
        previous = np.append((M @ (t[:-1] * problem.u_scale) + dudp * t[-1] * problem.span) / problem.u_scale, t[-1])
    elif M is not None and abs(t[-1]) < FOLD_TP:
        previous = np.append(M @ (t[:-1] * problem.u_scale) / problem.u_scale, t[-1])
    else:
        previous = e_p * (1.0 if t[-1] >= 0 else -1.0)
    return new, _tangent(new.jac, previous / np.linalg.norm(previous))


def continue_branch(residual: Residual, u0, p0: float, p_end: float, *, step: float | None = None,
                    max_steps: int = 200, tol: float = 1e-9, stability: Stability | None = None,
                    u_scale=1.0, max_step: float | None = None, min_step: float | None = None,
                    margin: float | None = None, locate_tol: float | None = None, unit_tol: float = 1e-6,
                    max_iter: int = 8, on_point: Callable[[BranchPoint], None] | None = None,
                    reanchor: Callable | None = None, events: Callable | None = None,
                    invariant: Callable | None = None, solve: Callable | None = None) -> Branch:
    """Follow the branch of r(u, p) = 0 through (u0, p0) towards p_end by pseudo-arclength (Keller 1977).

    - residual(u, p) -> (r (m,), J_u (m, m), J_p (m,)), real; u0 is first corrected at p = p0;
    - stability(u, p) -> multipliers (complex array, possibly empty; where their count changes along the
      branch, the missing ones count as 0), or None; called only at a (u, p) where ``residual`` was just evaluated
      (a corrected point), so a caller whose multipliers come with its Jacobian (an orbit's monodromy)
      may keep its last one;
    - ``tol`` bounds max |r| at every point (``max_iter`` Newton steps per correction);
    - ``step`` (the first), ``max_step``, ``min_step``: lengths along the branch in units of p
      (defaults |p_end - p0| / 50, / 10 and step / 1000); ``max_steps`` counts the accepted steps (not
      the trial points that locate special points);
    - ``u_scale`` (scalar or (m,)): the size of u that counts as much as the whole range of p;
    - ``margin`` (default |p_end - p0| / 10) widens the range a folded branch may leave;
    - ``locate_tol`` (default 1e-6 |p_end - p0|, about 17 halvings of the largest step): the length
      along the branch, in units of p, to which special points are located;
    - ``unit_tol``: the margin of the unit circle (a point is stable when every |mu| < 1 + unit_tol);
    - ``on_point(point)``: called with each accepted :class:`BranchPoint` as it is added (the first one too), e.g.
      to report progress or save the points so far;
    - ``reanchor(u, p, forced) -> None | (u_new, M) | (u_new, M, du_new/dp)``: a change of the unknowns'
      coordinates along the branch (an orbit's section moved): called at the start and after each accepted point
      (``forced`` False) and once when a step from a point fails down to ``min_step`` (True). None keeps them; (u_new, M) is
      the same solution in new coordinates, in which ``residual`` and ``stability`` work from then on, with
      M = du_new/du (m, m) or None and du_new/dp (m,) (the new state's change with p at a fixed old one) or None:
      the old tangent mapped by both orients the new one; without du_new/dp the tangent keeps its p component's
      sign, and near a fold (|t_p| < FOLD_TP) follows M du/ds. The point is
      re-corrected there at its p and the branch goes on from it; special points are located within one
      coordinate system (between two points, before the change), :attr:`Branch.reanchors` lists the changes and
      :attr:`BranchPoint.anchor` says which coordinates a point's u is in;
    - ``events(u, p) -> (structure, margin)``: the solution's non-smooth structure (hashable: equal where the same)
      and its margin >= 0 to a change of it (0 at a grazing, linear in the distance on either side); with it the
      branch crosses grazings (module docstring). Called, as ``stability``, only at corrected points;
    - ``invariant(u, p) -> array``: measures of the solution that do not depend on the coordinates (``reanchor``):
      a closed branch is recognised by them (and p) after the coordinates moved;
    - ``solve(u, p) -> u' or None``: the caller's own solver at p from u (an orbit's shooting), tried for the first
      point past a grazing when the corrector fails there.
    """
    if not callable(residual):
        raise NsfemError(f"continue_branch: residual must be callable, got {type(residual).__name__}")
    if stability is not None and not callable(stability):
        raise NsfemError(f"continue_branch: stability must be callable or None, got {type(stability).__name__}")
    try:
        u0 = np.array(u0, dtype=float)
    except (TypeError, ValueError):
        raise NsfemError("continue_branch: u0 must be an array of numbers") from None
    if u0.ndim != 1 or u0.size == 0:
        raise NsfemError(f"continue_branch: u0 must be a non-empty 1-D array, got shape {u0.shape}")
    if not np.all(np.isfinite(u0)):
        bad = int(np.flatnonzero(~np.isfinite(u0))[0])
        raise NsfemError(f"continue_branch: u0[{bad}] = {u0[bad]!r} is not finite")
    p0 = _finite_float("p0", p0)
    p_end = _finite_float("p_end", p_end)
    if p0 == p_end:
        raise NsfemError(f"continue_branch: p_end = p0 = {p0:g}: give a different end of the parameter range")
    span = abs(p_end - p0)
    if not math.isfinite(span) or span <= ROUNDOFF * max(abs(p0), abs(p_end)):
        raise NsfemError(f"continue_branch: the range p0 = {p0:g} to p_end = {p_end:g} must have a finite length "
                         f"above the round-off of p")
    step = _finite_float("step", step, positive=True, allow_none=True) or span / 50
    if step < ROUNDOFF * span:
        raise NsfemError(f"continue_branch: step = {step:g} is below the round-off of the range "
                         f"({ROUNDOFF:g} |p_end - p0| = {ROUNDOFF * span:g})")
    max_step = _finite_float("max_step", max_step, positive=True, allow_none=True) or max(span / 10, step)
    min_step = _finite_float("min_step", min_step, positive=True, allow_none=True) or max(step / 1000, ROUNDOFF * span)
    if not min_step <= step <= max_step:
        raise NsfemError(f"continue_branch: the steps must satisfy min_step <= step <= max_step, got {min_step:g}, "
                         f"{step:g}, {max_step:g}")
    if min_step < ROUNDOFF * span:
        raise NsfemError(f"continue_branch: min_step = {min_step:g} is below the round-off of the range "
                         f"({ROUNDOFF:g} |p_end - p0| = {ROUNDOFF * span:g})")
    margin = span / 10 if margin is None else _finite_float("margin", margin)
    if margin < 0:
        raise NsfemError(f"continue_branch: margin must be >= 0, got {margin:g}")
    locate_tol = _finite_float("locate_tol", locate_tol, positive=True, allow_none=True) or 1e-6 * span
    if locate_tol < ROUNDOFF * span:
        raise NsfemError(f"continue_branch: locate_tol = {locate_tol:g} is below the round-off of the range "
                         f"({ROUNDOFF:g} |p_end - p0| = {ROUNDOFF * span:g})")
    tol = _finite_float("tol", tol, positive=True)
    unit_tol = _finite_float("unit_tol", unit_tol)
    if unit_tol < 0:
        raise NsfemError(f"continue_branch: unit_tol must be >= 0, got {unit_tol:g}")
    for name, value in (("max_steps", max_steps), ("max_iter", max_iter)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise NsfemError(f"continue_branch: {name} must be a positive integer, got {value!r}")
    try:
        scale = np.broadcast_to(np.asarray(u_scale, dtype=float), u0.shape).copy()
    except (TypeError, ValueError):
        raise NsfemError(f"continue_branch: u_scale must be a number or an array of {u0.size} numbers") from None
    if not np.all(np.isfinite(scale) & (scale > 0)):
        raise NsfemError("continue_branch: u_scale must be finite and > 0")
    if on_point is not None and not callable(on_point):
        raise NsfemError(f"continue_branch: on_point must be callable or None, got {type(on_point).__name__}")
    if reanchor is not None and not callable(reanchor):
        raise NsfemError(f"continue_branch: reanchor must be callable or None, got {type(reanchor).__name__}")
    for name, value in (("events", events), ("invariant", invariant), ("solve", solve)):
        if value is not None and not callable(value):
            raise NsfemError(f"continue_branch: {name} must be callable or None, got {type(value).__name__}")
    said = on_point if on_point is not None else (lambda point: None)

    problem = _Scaled(residual, stability, u0.size, scale, p0, p_end, events, invariant, solve)
    ds, ds_max, ds_min, locate_z = step / span, max_step / span, min_step / span, locate_tol / span
    lo_z, hi_z = -margin / span, 1.0 + margin / span     # z_p of min(p0, p_end) - margin, max + margin

    z0 = problem.z(u0, p0)
    e_p = np.zeros(u0.size + 1)
    e_p[-1] = 1.0
    try:
        r0, _ = problem.evaluate(z0)
    except _Failure as exc:
        raise NsfemError(f"continue_branch: at the start (u0, p0 = {p0:g}): {exc}") from None
    try:
        a = _correct(problem, z0, e_p, 0.0, tol, max_iter)
    except _Failure as exc:
        start = BranchPoint(p0, u0, None, None, False, float(np.max(np.abs(r0))), 0.0)
        return Branch([start], [], "failed", f"the start at p = {p0:g} did not converge: {exc}")
    try:
        problem.complete(a)
    except _Failure as exc:
        return Branch([_branch_point(problem, a, 0.0, tol, unit_tol)], [], "failed", f"at the start: {exc}")
    t = _tangent(a.jac, e_p)
    points = [_branch_point(problem, a, 0.0, tol, unit_tol)]
    said(points[-1])
    bifurcations: list[dict] = []
    reanchors: list[dict] = []
    anchor = 0
    s = 0.0

    def move(pt: _Point, t: np.ndarray, forced: bool):
        """The point and tangent in the coordinates reanchor moves to, recorded; None when it keeps them."""
        nonlocal anchor
        out = _reanchored(problem, reanchor, pt, t, forced, tol, max_iter)
        if out is not None:
            anchor += 1
            reanchors.append({"index": len(points) - 1, "value": points[-1].p, "anchor": anchor, "forced": forced,
                              "multipliers_before": pt.multipliers, "multipliers_after": out[0].multipliers})
            mb, ma = pt.multipliers, out[0].multipliers
            if mb is not None and ma is not None:
                # the same spectrum in both coordinates, up to round-off: a multiplier that round-off puts on the
                # other side of 1 + unit_tol is a crossing at this very point, which no chord (each within one
                # coordinate system) would see
                n = max(mb.size, ma.size)
                for i, j in _crossings(_padded(mb, n), _padded(ma, n), unit_tol):
                    bifurcations.append({"kind": _kind(complex(_padded(ma, n)[j])), "value": problem.p(out[0].z),
                                         "index": len(points) - 1, "u": problem.u(out[0].z),
                                         "multipliers": ma, "accuracy": 0.0, "detected_by": "multipliers",
                                         "anchor": anchor})
        return out

    def ended(stop: str, reason: str) -> Branch:
        return Branch(points, bifurcations, stop, reason, reanchors)

    def cross(a: _Point, t: np.ndarray, b: _Point | None, ds_tried: float):
        """Over the grazing ahead of a (b: a point past it, if a step reached one): (the grazing point, the first
        point past it, its tangent, what was found) or None when it is not found."""
        past = None if b is None else float(t @ (b.z - a.z))
        if past is not None and past <= 0.0:
            return None
        side = _graze_point(problem, a, t, past, tol, max_iter, GRAZE_LOCATE * locate_z, before=before,
                            first=0.5 * ds_tried)
        if side is None:
            return None
        g_a, acc_a = side
        if b is None and not acc_a <= GRAZE_REACH * ds_tried:
            return None    # (the margin does not fall to 0 within reach: the step failed for another reason)
        if b is None:
            h = abs(ds_tried * t[-1]) if abs(t[-1]) > FOLD_TP else ds_tried
            b = _beyond(problem, g_a, t, a.structure, [h, 4 * h, h / 4, 16 * h, h / 16], tol, max_iter)
            if b is None:
                return None
        # and from b's side back towards it: the better located of the two (one side's corrector may not get near
        # the grazing: next to it an impacting orbit's Newton basin shrinks with its approach speed)
        back = g_a.z - b.z
        length = float(np.linalg.norm(back))
        g, acc = g_a, acc_a
        if length > 0 and acc_a > GRAZE_LOCATE * locate_z:
            other = _graze_point(problem, b, back / length, length, tol, max_iter, GRAZE_LOCATE * locate_z,
                                 first=0.5 * length)
            if other is not None and other[1] < acc_a:
                g, acc = other
        if acc > max(locate_z, 1e-3 * length) and acc > 0.25 * float(np.linalg.norm(b.z - a.z)):
            return None    # (neither side's margin came near 0: no grazing located there)
        if not lo_z < g.z[-1] < 1.0:
            return None    # (past p_end or out of the range: the ordinary step ends the branch)
        return g, b, None, {"accuracy": acc, "side_point": g_a, "side_tangent": _tangent(g_a.jac, t)}

    first_anchor = None
    excursion = 0.0   # (the invariant's largest distance from the first point's so far: its scale for a closing)
    before = None     # the point before a, in a's coordinates (None after a move)
    while True:
        if reanchor is not None:   # the coordinates at the point the step starts from (the start's too)
            try:
                out = move(a, t, False)
            except _Failure as exc:
                return ended("failed", f"at {'the start ' if len(points) == 1 else ''}p = {points[-1].p:.10g}: {exc}")
            if out is not None:
                a, t = out
                before = None
        if first_anchor is None:   # (a closed branch is seen in the coordinates of the first step, or by its invariant)
            first_anchor, first_z, first_point = anchor, a.z, a
        if len(points) - 1 >= max_steps:
            return ended("max_steps", f"stopped after max_steps = {max_steps} steps at p = {points[-1].p:.10g}")
        # predictor-corrector, the step halved until a correction succeeds
        failure = ""
        ds_first, moved_here, graze_tried, crossing, unjoined = ds, False, False, None, False
        while True:
            z_pred = a.z + ds * t
            try:
                b = _correct(problem, z_pred, t, float(t @ z_pred), tol, max_iter)
                tb = _tangent(b.jac, t)
                if np.linalg.norm(b.z - z_pred) > ds:
                    raise _Failure(f"the corrector moved farther than the step from the predictor at p = "
                                   f"{problem.p(b.z):.10g}")
                if problem.events is not None:
                    problem.complete(b)
                # (across a change of structure the tangent is discontinuous: its turn is the kink's, not a jump
                # to another branch)
                kinked = problem.events is not None and b.structure != a.structure
                if (kinked and not _kink_joins(a, t, b, tb, before)) or (tb @ t < MAX_TURN_COS and not kinked):
                    # over a change of structure the tangent's turn is the kink's, whatever it is, when the two sides'
                    # tangent lines meet between a and b (:func:`_kink_joins`); else the corrector landed on the other
                    # structure's far arm past a fold next to the grazing (the branch turning back there, as
                    # Nordmark's square root may: the fold skipped), so the grazing, within the step, is located and
                    # the point past it found joined to it (:func:`_joins`), or the step fails
                    if kinked and not graze_tried:
                        graze_tried = True
                        crossing = cross(a, t, None, ds)
                        if crossing is not None:
                            break
                    unjoined = unjoined or kinked
                    raise _Failure(f"the tangent turned by {math.degrees(math.acos(max(-1.0, tb @ t))):.0f} "
                                   f"degrees in one step at p = {problem.p(b.z):.10g}"
                                   + (" onto another structure whose tangent line does not meet this side's"
                                      if kinked else ""))
                if b.z[-1] >= 1.0 > a.z[-1]:     # passed p_end: the last point exactly at p_end
                    theta = (1.0 - a.z[-1]) / (b.z[-1] - a.z[-1])
                    b = _correct(problem, a.z + theta * (b.z - a.z), e_p, 1.0, tol, max_iter)
                    tb = _tangent(b.jac, t)
                    problem.complete(b)
                elif problem.events is None:
                    problem.complete(b)
                break
            except _Failure as exc:
                failure = str(exc)
                if problem.events is not None and not graze_tried and _grazing_ahead(a, before, t, ds):
                    graze_tried = True     # (a grazing ahead changes the orbit's events: the step cannot pass it)
                    crossing = cross(a, t, None, ds)
                    if crossing is not None:
                        break
                ds *= 0.5
                if ds < ds_min and reanchor is not None and not moved_here:
                    # (the branch would stop here: new coordinates, if the caller has any, and the step again)
                    moved_here = True
                    try:
                        out = move(a, t, True)
                    except _Failure as exc2:
                        out, failure = None, f"{failure}; {exc2}"
                    if out is not None:
                        (a, t), ds, before = out, ds_first, None
                        continue
                if ds < ds_min:
                    return ended("failed", f"no correction from p = {points[-1].p:.10g} with steps down to min_step = "
                                           f"{min_step:g}: {failure}" + (
                                               "; a step landed on another structure not joined to this side through "
                                               "a grazing (that side folds back next to it?)" if unjoined else ""))
        passed = None
        if crossing is None and problem.events is not None and b.structure != a.structure:
            # the step went over a grazing (the events changed) without failing: bracketed by the step, not located
            # (a branch near grazing all along, as the crack's micro-separations, passes dozens; a step that fails
            # at one locates it)
            ma, mb = a.margin, b.margin
            theta = ma / (ma + mb) if math.isfinite(ma) and math.isfinite(mb) and ma + mb > 0 else 0.5
            zg = a.z + theta * (b.z - a.z)
            passed = {"kind": "grazing", "value": problem.p(zg), "index": len(points) - 1, "u": problem.u(zg),
                      "multipliers": None, "accuracy": float(np.linalg.norm(b.z - a.z)) * span,
                      "detected_by": "events", "anchor": anchor, "structure_before": a.structure,
                      "structure_after": b.structure, "margin": math.nan, "located": False}
        if crossing is not None:
            g, b, _, graze = crossing
            # the grazing point, then the first point beyond it (its own side: its tangent from the secant)
            chord = float(np.linalg.norm(g.z - a.z))
            s += chord * span
            if chord > 0:
                found = _special_points(problem, a, t, graze["side_point"], graze["side_tangent"], len(points) - 1,
                                        tol, max_iter, locate_z, unit_tol)
                for f in found:
                    f["anchor"] = anchor
                bifurcations += found
                points.append(_branch_point(problem, g, s, tol, unit_tol, anchor))
                said(points[-1])
            bifurcations.append({"kind": "grazing", "value": problem.p(g.z), "index": len(points) - (2 if chord else 1),
                                 "u": problem.u(g.z), "multipliers": g.multipliers,
                                 "accuracy": graze["accuracy"] * span,
                                 "detected_by": "events", "anchor": anchor, "structure_before": a.structure,
                                 "structure_after": b.structure, "margin": g.margin, "located": True})
            if b.z[-1] >= 1.0 > g.z[-1]:     # passed p_end: the last point exactly at p_end
                try:
                    b = problem.complete(_correct(problem, b.z, e_p, 1.0, tol, max_iter))
                except _Failure as exc:
                    return ended("failed", f"after the grazing at p = {problem.p(g.z):.10g}: {exc}")
            a, t = g, _tangent(b.jac, (b.z - g.z) / max(float(np.linalg.norm(b.z - g.z)), 1e-300))
            tb = t
            # (the step the side before the grazing took: the side after is as smooth away from it)
            ds = min(max(float(np.linalg.norm(b.z - g.z)), ds_first, ds_min), ds_max)
        chord = float(np.linalg.norm(b.z - a.z))
        s += chord * span
        found = [] if crossing is not None else _special_points(problem, a, t, b, tb, len(points) - 1, tol, max_iter,
                                                                locate_z, unit_tol)
        for f in found:
            f["anchor"] = anchor
        bifurcations += found
        if passed is not None:
            bifurcations.append(passed)
        points.append(_branch_point(problem, b, s, tol, unit_tol, anchor))
        said(points[-1])
        if b.z[-1] >= 1.0:
            return ended("end", f"reached p_end = {p_end:g}")
        if not lo_z <= b.z[-1] <= hi_z:
            return ended("left", f"the branch folded back and left [{min(p0, p_end) - margin:g}, "
                                 f"{max(p0, p_end) + margin:g}] at p = {points[-1].p:.10g}")
        if b.invariant is not None and first_point.invariant is not None:
            excursion = max(excursion, float(np.linalg.norm(b.invariant - first_point.invariant)))
        if len(points) > 3 and s > 3 * chord * span and _returned(a, b, first_z if anchor == first_anchor else None,
                                                                     first_point, excursion):
            return ended("closed", f"the branch returned to its first point (p = {p0:g}) after a length {s:.6g} "
                                   "in units of p: a closed branch")
        if crossing is None and b.iterations <= GROW_ITERATIONS and (tb @ t > EASY_TURN_COS
                                                                     or b.structure != a.structure):
            ds = min(ds * GROW, ds_max)
        before, (a, t) = a, (b, tb)


def critical_vector(monodromy, target: complex = -1.0) -> tuple[complex, np.ndarray]:
    """The eigenvalue of a square matrix closest to ``target`` (-1: the period-doubling multiplier) and
    its eigenvector, unit 2-norm, its largest component real and positive (so real for a real
    eigenvalue of a real matrix). A branch switch starts the doubled orbit from u + h v."""
    try:
        a = np.asarray(monodromy, dtype=complex)
        target = complex(target)
    except (TypeError, ValueError):
        raise NsfemError("critical_vector: the matrix and the target must be numbers") from None
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.size == 0:
        raise NsfemError(f"critical_vector: the matrix must be square and non-empty, got shape {a.shape}")
    if not (np.all(np.isfinite(a)) and np.isfinite(target)):
        raise NsfemError("critical_vector: the matrix and the target must be finite")
    real = not np.any(a.imag)
    values, vectors = np.linalg.eig(a.real if real else a)
    k = int(np.argmin(np.abs(values - target)))
    v = vectors[:, k]
    big = int(np.argmax(np.abs(v)))
    v = v * (abs(v[big]) / v[big])
    v = v / np.linalg.norm(v)
    mu = complex(values[k])
    if real and mu.imag == 0.0:
        return mu, v.real.copy()
    return mu, v
