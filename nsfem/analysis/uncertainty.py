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

import math
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


def linearized(J: np.ndarray, r: np.ndarray, u: np.ndarray, level: float = 0.95, floor: float = 0.0) -> Uncertainty:
    """Intervals, correlation and identifiability from the Jacobian ``J`` (N, p) and residuals ``r``
    (N,) at the estimate ``u`` (p,) in the unit box. The residual variance is
    s^2 = max(RSS, N floor^2) / (N - p): ``floor`` is the RMS residual below which a misfit is
    resolution, not noise (as in :func:`same_fit`); a fit to round-off (noise-free data) gets intervals
    of that resolution instead of the round-off's, which would exclude the truth."""
    from scipy.stats import t as student

    J, r, u = np.asarray(J, float), np.asarray(r, float), np.asarray(u, float)
    n, p = J.shape
    _, S, Vt = np.linalg.svd(J, full_matrices=False)
    top = S[0] if S.size and S[0] > 0 else 1.0
    rel = S / top
    rank = int(np.count_nonzero((rel > RANK_RTOL) & (S > 0)))
    dof = n - p
    s2 = float(max(r @ r, n * floor**2) / dof) if dof > 0 else np.inf
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


def same_fit(rss: float, rss_other: float, n: int, p: int, floor: float = 0.0) -> tuple[float, float]:
    """(F, p-value) of the F-test whether the minimum with residual sum of squares ``rss_other``
    fits the same ``n`` data worse than the one with ``rss`` (each fitted with ``p`` parameters):
    F = (RSS_other + n floor^2) / (RSS + n floor^2) with (n - p, n - p) degrees of freedom, the
    p-value P(F_{n-p, n-p} >= F). ``floor`` is the RMS residual below which a misfit is resolution
    (run reproducibility, optimizer tolerance), not information: noise-free data fitted twice to
    round-off give F near 1 instead of a ratio of two round-offs. A p-value of 0.05 or more: the data
    cannot tell the two minima apart.

    >>> [round(x, 3) for x in same_fit(1.0, 1.0, 101, 1)]
    [1.0, 0.5]
    """
    from scipy.stats import f as fisher

    dof = n - p
    if dof <= 0:
        return math.nan, math.nan
    F = (rss_other + n * floor**2) / (rss + n * floor**2) if rss + n * floor**2 > 0 else math.inf
    return float(F), float(fisher.sf(F, dof, dof))


@dataclass(frozen=True)
class Whiteness:
    """Lag-1 autocorrelation of the residuals per sensor (``rho``), its one-sided bound ``z / sqrt(k)``
    for ``k`` white samples (``bound``) and the sensors above it (``structured``)."""

    rho: np.ndarray
    bound: float
    structured: np.ndarray


def whiteness(r: np.ndarray, sensors: int, level: float = 0.01) -> Whiteness:
    """Whether the residuals ``r`` (sample-major, ``sensors`` columns) look like white noise: per
    sensor, the lag-1 autocorrelation rho = sum r_i r_(i+1) / sum r_i^2 against its large-sample
    bound z / sqrt(k) (rho of k white samples is about normal with variance 1 / k), z the one-sided
    normal quantile at ``level`` / sensors (Bonferroni: white residuals exceed it in some sensor
    with probability ``level``). A model that misses a smooth part of the signals (a wrong minimum,
    a wrong model) leaves smooth residuals, rho near 1.

    >>> w = whiteness(np.random.default_rng(0).standard_normal(2000), 2)
    >>> w.structured.tolist(), round(w.bound, 3)
    ([False, False], 0.081)
    >>> whiteness(np.sin(np.linspace(0, 6, 2000)), 2).structured.tolist()
    [True, True]
    """
    from scipy.stats import norm

    R = np.asarray(r, float).reshape(-1, sensors)
    k = R.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.sum(R[1:] * R[:-1], axis=0) / np.sum(R**2, axis=0)
    rho = np.where(np.isfinite(rho), rho, 0.0)
    bound = float(norm.ppf(1.0 - level / sensors) / math.sqrt(max(k, 1)))
    return Whiteness(rho, bound, rho > bound)


def autocorrelation_time(x: np.ndarray) -> tuple[float, np.ndarray]:
    """(tau, rho) of the series ``x``: its autocorrelation rho(l) over the lags of Geyer's initial
    positive sequence (pairs rho(2m) + rho(2m + 1) summed while positive: beyond them the estimate is
    noise) and the integrated autocorrelation time tau = 1 + 2 sum_{l >= 1} rho(l), at least 1: k
    correlated samples inform a mean as k / tau white ones would. White noise has tau near 1, an AR(1)
    series (1 + a) / (1 - a).

    >>> a, e = 0.9, np.random.default_rng(0).standard_normal(20000)
    >>> x = np.zeros_like(e)
    >>> for i in range(1, e.size): x[i] = a * x[i - 1] + e[i]
    >>> tau, rho = autocorrelation_time(x)
    >>> bool(abs(tau / ((1 + a) / (1 - a)) - 1) < 0.2), round(float(rho[1]), 2)
    (True, 0.9)
    """
    x = np.asarray(x, float) - np.mean(x)
    k = x.size
    f = np.fft.rfft(x, 2 * k)
    acov = np.fft.irfft(f * np.conj(f))[:k]
    if not acov[0] > 0:
        return 1.0, np.ones(1)
    rho = acov / acov[0]
    m = 0
    while 2 * m + 1 < k and rho[2 * m] + rho[2 * m + 1] > 0:
        m += 1
    rho = rho[:max(2 * m, 1)]
    return max(1.0, float(2.0 * np.sum(rho) - 1.0)), rho


def correlated(unc: Uncertainty, J: np.ndarray, r: np.ndarray, u: np.ndarray, sensors: int,
               structured: np.ndarray, level: float = 0.95) -> tuple[Uncertainty, np.ndarray]:
    """``unc`` (from :func:`linearized`) with the ``structured`` sensors' residual autocorrelation
    taken into the covariance, and their autocorrelation times (1 for the others). ``J`` (N, p) and
    ``r`` (N,) are sample-major with ``sensors`` columns. Per structured sensor the residuals'
    autocorrelation rho(l) (:func:`autocorrelation_time`) enters the sandwich covariance
    H^+ Omega H^+, H = J^T J, Omega = s^2 sum_s [A_s(0) + sum_l rho_s(l) (A_s(l) + A_s(l)^T)] with
    A_s(l) = sum_t J_ts^T J_(t+l)s (white residuals: Omega = s^2 H, the linearized covariance); the
    Student quantile takes N / mean(tau) - p degrees of freedom. A key's half-width is never below the
    white one (a correlation estimate that cancels is no information). Correlations between sensors are
    not modelled."""
    from dataclasses import replace

    from scipy.stats import t as student

    J, r = np.asarray(J, float), np.asarray(r, float)
    n, p = J.shape
    tau = np.ones(sensors)
    if not np.any(structured) or not math.isfinite(unc.s2) or n % sensors:
        return unc, tau
    k = n // sensors
    R, Js = r.reshape(k, sensors), J.reshape(k, sensors, p)
    omega = J.T @ J
    for s in np.flatnonzero(structured):
        tau[s], rho = autocorrelation_time(R[:, s])
        for lag in range(1, rho.size):
            A = Js[:-lag, s].T @ Js[lag:, s]
            omega += rho[lag] * (A + A.T)
    _, S, Vt = np.linalg.svd(J, full_matrices=False)
    seen = Vt.T[:, :unc.rank]
    hinv = (seen / S[:unc.rank] ** 2) @ seen.T
    cov = hinv @ omega @ hinv * unc.s2
    determined = np.isfinite(unc.sigma)
    sigma = np.where(determined, np.maximum(unc.sigma, np.sqrt(np.maximum(np.diag(cov), 0.0))), np.inf)
    dof = max(int(n / float(np.mean(tau))) - p, 1)
    tq = max(float(student.ppf(0.5 + level / 2, dof)), unc.t)
    half_white = np.maximum(u - unc.interval[:, 0], unc.interval[:, 1] - u)
    half = np.where(determined, np.maximum(tq * sigma, half_white), np.inf)
    interval = np.column_stack([np.clip(u - half, 0.0, 1.0), np.clip(u + half, 0.0, 1.0)])
    corr = unc.correlation.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        c = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    ok = np.outer(determined, determined) & np.isfinite(c)
    corr[ok] = np.clip(c[ok], -1.0, 1.0)
    return replace(unc, interval=interval, sigma=sigma, correlation=corr, dof=dof, t=tq), tau
