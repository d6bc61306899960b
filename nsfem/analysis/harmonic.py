"""The steady harmonic of sampled signals: one frequency's amplitude and phase by least squares.

A signal x(t) is fitted by an offset and one harmonic of the angle theta(t) = 2 pi f t + theta0,

    x(t) ~ c + a cos(theta) + b sin(theta) = c + A cos(theta - phi),   A = hypot(a, b), phi = atan2(b, a),

so phi is the phase lag of the signal's positive peak behind theta = 0 (for a rotor's 1x: behind the
once-per-revolution mark of the rotation angle). Over a whole number of periods of uniform samples the
fit is the signal's Fourier coefficient at f: it is exact for a sampled sinusoid, whatever the samples'
positions on its peaks (half the peak-to-peak is low by up to 1 - cos(pi f dt)), and the other
harmonics of f (2x, 3x, ...) and the offset do not enter it.

>>> t = np.arange(80) / 800.0                       # 8 periods of 10 Hz, 10 samples a period
>>> x = 0.5 + 2.0 * np.cos(2 * np.pi * 10 * t - 1.0) + 0.3 * np.cos(4 * np.pi * 10 * t)
>>> c, a, b = harmonic_fit(t, x, 10.0)
>>> [round(float(v), 12) for v in (c, np.hypot(a, b), np.arctan2(b, a))]
[0.5, 2.0, 1.0]
"""

from __future__ import annotations

import math

import numpy as np


def harmonic_fit(t: np.ndarray, x: np.ndarray, frequency_hz: float, theta0: float = 0.0) -> np.ndarray:
    """Least-squares (c, a, b) of x ~ c + a cos(theta) + b sin(theta), theta = 2 pi f t + theta0 [rad].

    ``x`` is (n,) or (n, k) (k signals on the same times); returns (3,) or (3, k). Needs ``f`` > 0 and
    samples that tell cos from sin (at least three a period, spread over it)."""
    t = np.asarray(t, dtype=float)
    theta = 2 * math.pi * frequency_hz * t + theta0
    basis = np.column_stack([np.ones_like(t), np.cos(theta), np.sin(theta)])
    coef, *_ = np.linalg.lstsq(basis, np.asarray(x, dtype=float), rcond=None)
    return coef


def amplitude_phase(coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, phi [deg] in [0, 360)) of fitted (c, a, b): x ~ c + A cos(theta - phi)."""
    a, b = coef[1], coef[2]
    return np.hypot(a, b), np.mod(np.degrees(np.arctan2(b, a)), 360.0)


def whole_periods(t: np.ndarray, frequency_hz: float, share: float = 0.5) -> np.ndarray:
    """The samples of the last ``share`` of the span of ``t`` cut to a whole number m of periods ending
    at t[-1] (a boolean mask; the sample one period-count before the end left out, so that uniform samples
    cover the m periods once). No sample when the share holds less than one period.

    >>> int(whole_periods(np.arange(101) / 100.0, 3.0).sum())     # 0.5 s: one period of 1/3 s, 33 samples
    33
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2 or frequency_hz <= 0:
        return np.zeros(t.size, dtype=bool)
    period = 1.0 / frequency_hz
    m = math.floor(share * (t[-1] - t[0]) / period * (1 + 1e-12))
    if m < 1:
        return np.zeros(t.size, dtype=bool)
    dt = float(np.median(np.diff(t)))
    return t > t[-1] - m * period + 0.5 * min(dt, period)


def steady_harmonic(t: np.ndarray, x: np.ndarray, frequency_hz: float, theta0: float = 0.0,
                    share: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, phi [deg], drift) per signal (columns of ``x``, (n, k)) of the harmonic fitted over
    :func:`whole_periods` of the last ``share`` of the run; ``drift`` is |A_late - A_early| / A between
    the fits over the window's later and earlier halves (whole periods each): how far from steady the
    harmonic still is. NaN where undefined: A and phi with less than one period, drift with less than two.

    >>> t = np.arange(4001) / 1000.0                 # 4 s of 5 Hz, decaying at 0.2 1/s
    >>> A, phi, drift = steady_harmonic(t, (np.exp(-0.2 * t) * np.cos(10 * np.pi * t))[:, None], 5.0)
    >>> round(float(drift[0]), 4), round(2 * math.tanh(0.1), 4)   # the mean envelopes of 2-3 s and 3-4 s
    (0.1993, 0.1993)
    """
    x = np.asarray(x, dtype=float).reshape(len(t), -1)
    nan = np.full(x.shape[1], np.nan)
    window = whole_periods(t, frequency_hz, share)
    if not window.any():
        return nan, nan.copy(), nan.copy()
    A, phi = amplitude_phase(harmonic_fit(t[window], x[window], frequency_hz, theta0))
    m = round((t[-1] - t[window][0]) * frequency_hz)   # the window's periods
    if m < 2:
        return A, phi, nan
    late = whole_periods(t, frequency_hz, share=(m // 2 + 0.5) / (frequency_hz * (t[-1] - t[0])))
    early = window & ~late
    a_late = amplitude_phase(harmonic_fit(t[late], x[late], frequency_hz, theta0))[0]
    a_early = amplitude_phase(harmonic_fit(t[early], x[early], frequency_hz, theta0))[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        drift = np.abs(a_late - a_early) / A
    return A, phi, drift
