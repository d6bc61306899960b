"""Linearized uncertainty of a least-squares estimate: Gauss-Newton intervals and identifiability.

Parameters are scaled to the unit box (u = (x - low) / (high - low)), so the Jacobian J = dr/du of
the relative residuals r compares parameters of any unit. With s^2 = |r|^2 / (N - p) the residual
variance, the covariance is s^2 (J^T J)^-1 and the 95 % interval is u +- t_{0.975, N-p} sigma
(Student t: s^2 is estimated from the same residuals).

Identifiability comes from the singular values S of J. A direction the sensors do not see has a
column of finite differences of round-off: |J v| ~ sqrt(N) eps_run / h, about 1e-8 sqrt(N) for a
run reproducible to 1e-12 and a step h = 1e-4, while a parameter that moves the signals by a few
per cent of their RMS over its range gives S ~ 1e-2 sqrt(N) or more; both grow as sqrt(N), so the
rank is decided relative to the largest, at :data:`RANK_RTOL` = 1e-6, with two orders of margin
either side. A direction the data see too weakly is also reported: its 95 % half-width
t s / S_k exceeds the box (1 in unit scale), so the data leave it anywhere in the ranges.

>>> J = np.array([[1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
>>> u = linearized(J, np.array([0.01, -0.01, 0.0]), np.array([0.5, 0.5]))
>>> u.rank, [w.reason for w in u.weak], np.round(u.interval[0], 3).tolist(), u.interval[1].tolist()
(1, ['rank'], [0.373, 0.627], [0.0, 1.0])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: singular values below this fraction of the largest count as zero (see the module's text)
RANK_RTOL = 1e-6
#: a parameter whose component in an unseen direction exceeds this is not determined at all
NULL_COMPONENT = 1e-8
#: a key is among the dominant ones of a direction when it carries this share of it (|v_k|^2)
DOMINANT_SHARE = 0.1


@dataclass(frozen=True)
class WeakDirection:
    """A combination of parameters (unit-scaled, unit norm) the data do not determine: ``rank`` (the
    Jacobian does not see it) or ``range`` (its interval exceeds the box)."""

    direction: np.ndarray
    reason: str
    singular_value: float

    def dominant(self) -> np.ndarray:
        """Indices of the parameters that make up the direction (share >= :data:`DOMINANT_SHARE`)."""
        return np.flatnonzero(self.direction**2 >= DOMINANT_SHARE)


@dataclass(frozen=True)
class Uncertainty:
    """Gauss-Newton statistics at an estimate ``u`` (unit box): ``interval`` (p, 2) clipped to [0, 1],
    ``sigma`` (p,) (inf where undetermined), ``correlation`` (p, p) (NaN where undetermined),
    ``singular`` values of J relative to the largest, its ``rank``, ``s2``, ``dof``, ``t`` quantile
    and the ``weak`` directions."""

    interval: np.ndarray
    sigma: np.ndarray
    correlation: np.ndarray
    singular: np.ndarray
    rank: int
    s2: float
    dof: int
    t: float
    weak: tuple[WeakDirection, ...]

    @property
    def spans_range(self) -> np.ndarray:
        """Per parameter, whether its interval is the whole range (the data do not determine it)."""
        return (self.interval[:, 0] <= 0.0) & (self.interval[:, 1] >= 1.0)


def linearized(J: np.ndarray, r: np.ndarray, u: np.ndarray, level: float = 0.95) -> Uncertainty:
    """Intervals, correlation and identifiability from the Jacobian ``J`` (N, p) and residuals ``r``
    (N,) at the estimate ``u`` (p,) in the unit box."""
    from scipy.stats import t as student

    J, r, u = np.asarray(J, float), np.asarray(r, float), np.asarray(u, float)
    n, p = J.shape
    _, S, Vt = np.linalg.svd(J, full_matrices=False)
    top = S[0] if S.size and S[0] > 0 else 1.0
    rel = S / top
    rank = int(np.count_nonzero((rel > RANK_RTOL) & (S > 0)))
    dof = n - p
    s2 = float(r @ r / dof) if dof > 0 else np.inf
    tq = float(student.ppf(0.5 + level / 2, dof)) if dof > 0 else np.inf
    V = Vt.T
    seen, unseen = V[:, :rank], V[:, rank:]
    with np.errstate(divide="ignore", invalid="ignore"):
        cov = (seen / S[:rank] ** 2) @ seen.T * s2 if rank else np.zeros((p, p))
        var = np.diag(cov).copy()
        undetermined = np.any(np.abs(unseen) > NULL_COMPONENT, axis=1)
        var[undetermined] = np.inf
        sigma = np.sqrt(np.maximum(var, 0.0))
        half = tq * sigma
        half = np.where(np.isnan(half), np.inf, half)   # inf t times a zero sigma: no information
        interval = np.column_stack([np.clip(u - half, 0.0, 1.0), np.clip(u + half, 0.0, 1.0)])
        corr = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    corr[undetermined, :] = np.nan
    corr[:, undetermined] = np.nan
    np.fill_diagonal(corr, np.where(undetermined, np.nan, 1.0))
    weak = [WeakDirection(V[:, k], "rank", float(rel[k])) for k in range(rank, p)]
    weak += [WeakDirection(V[:, k], "range", float(rel[k])) for k in range(rank)
             if not tq * np.sqrt(s2) / S[k] <= 1.0]
    return Uncertainty(interval, sigma, corr, rel, rank, s2, dof, tq, tuple(weak))
