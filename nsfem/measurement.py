"""Measured sensor signals (``nsfem fit --data``) and their misfit against simulated ones.

A measurement is a CSV like the ``sensors.csv`` that ``nsfem run`` writes: a column ``t`` [s] on the
scene's clock (0 is the scene's ``[initial]`` state) and one column [m] per sensor, named as a
``[[sensor]]`` of the scene. Its columns choose the sensors that are fitted: a sensor of the scene
without a column is not fitted (a probe that was not recorded), a column that names no sensor is
an error.

Residuals are relative: each sensor's difference is divided by the measured signal's RMS (or, for
``spectrum``, by the RMS of its amplitude spectrum), so sensors weigh alike whatever their
amplitude, and the RMS of all residuals is the relative RMS misfit.

>>> m = Measurement(np.array([0.0, 0.1, 0.2]), ("a",), np.array([[1.0], [-1.0], [1.0]]))
>>> round(relative_rms(residuals(m.values + 0.1, m, "time")), 12)
0.1
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import NsfemError

MISFITS = ("time", "spectrum")
#: steps of t that differ by less than this fraction of their median count as uniform (``spectrum``)
UNIFORM = 1e-6
#: a step of t below this fraction of the median step is refused: the runs output at the data's
#: smallest step, so one duplicated time stamp (a logger's double write, a CSV rounded to fewer
#: digits) would make every run output a thousand times more often than the data were sampled
CLOSE = 1e-3


#: the largest magnitude of a sample, and the smallest RMS of a signal: the misfit squares residuals
#: (differences over a signal's RMS) and sums them over up to 1e7 samples, so samples and RMS within
#: 1e-100..1e100 keep every square and sum finite (1e200 x 1e7 << 1.8e308) with room for the simulated
#: signals; a displacement in metres outside them is a unit or export error, never a measurement
ABSURD = 1e100
#: a step of t above this many median steps is a gap in the record: the runs would simulate through it
#: (a gap of 1000 s in samples 1 ms apart: a million outputs per run that no sample is compared with)
GAP = 1000.0
#: a number in a CSV cell: decimal digits with an optional fraction and exponent, or nan/inf words
#: (refused later with their line). Python's float() also takes ``1_0e-5`` (as 1e-4: a garbled
#: 1,0e-5?), words like ``infinity``, digits of other scripts (``１``); a measurement takes none
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:nan|inf)", re.IGNORECASE)


@dataclass(frozen=True)
class Measurement:
    """Sampled signals: times ``t`` (k,), sensor ``names`` and ``values`` (k, len(names)); ``lines``
    the file's line of each sample (None when not read from a file)."""

    t: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    lines: tuple[int, ...] | None = None


def parse_number(cell: str) -> float:
    """A CSV cell as a float, strictly (:data:`NUMBER`): ValueError for anything else.

    >>> parse_number(" 1.5e-3 "), parse_number("-2")
    (0.0015, -2.0)
    >>> parse_number("1_0e-5")
    Traceback (most recent call last):
    ValueError: '1_0e-5' is not a decimal number
    """
    text = cell.strip()
    if not NUMBER.fullmatch(text):
        raise ValueError(f"{text!r} is not a decimal number")
    return float(text)


def read_measurement(path: str | Path) -> Measurement:
    """The measurement in CSV file ``path`` (checked by :func:`check_measurement`, whose errors name
    the file's lines)."""
    path = Path(path)
    what = f"--data {path}"
    if not path.is_file():
        raise NsfemError(f"{what}: no such file")
    try:
        text = path.read_text(encoding="utf-8-sig")   # a spreadsheet's byte-order mark is not part of the header
    except (OSError, UnicodeDecodeError) as exc:
        raise NsfemError(f"{what}: cannot read it as UTF-8 text ({exc})") from None
    reader = csv.reader(io.StringIO(text))
    try:
        rows = [(reader.line_num, r) for r in reader if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise NsfemError(f"{what}: line {reader.line_num}: not CSV ({exc})") from None
    if not rows:
        raise NsfemError(f"{what}: the file is empty")
    head = [c.strip() for c in rows[0][1]]
    if len(head) > 2 and not head[-1] and all(len(r) == len(head) and not r[-1].strip() for _, r in rows):
        # a delimiter at the end of every line (some loggers write one): an empty last field, no column
        head, rows = head[:-1], [(line, r[:-1]) for line, r in rows]
    if "t" not in head:
        raise NsfemError(f"{what}: no column 't' (the header is {','.join(head)!r}; the first column names the "
                         "time, the others sensors)")
    twice = sorted({h for h in head if head.count(h) > 1})
    if twice:
        raise NsfemError(f"{what}: column {twice[0]!r} appears {head.count(twice[0])} times in the header (give each "
                         "sensor one column)")
    data = np.empty((len(rows) - 1, len(head)))
    for i, (line, row) in enumerate(rows[1:]):
        if len(row) != len(head):
            raise NsfemError(f"{what}: line {line} has {len(row)} fields, the header {len(head)}")
        for j, cell in enumerate(row):
            try:
                data[i, j] = parse_number(cell)
            except ValueError:
                raise NsfemError(f"{what}: line {line}, column {head[j]!r}: {cell.strip()!r} is not a number "
                                 "(plain decimals such as -1.25e-5: no underscores, commas or units)") from None
    k = head.index("t")
    names = tuple(h for j, h in enumerate(head) if j != k)
    return check_measurement(data[:, k], dict(zip(names, data[:, [j for j in range(len(head)) if j != k]].T)),
                             what, tuple(line for line, _ in rows[1:]))


def check_measurement(t, signals: dict, what: str = "data", lines: tuple[int, ...] | None = None) -> Measurement:
    """A :class:`Measurement` from times and {sensor name: samples}: at least two samples, t finite,
    non-negative and increasing (no step below :data:`CLOSE` of the median, none above :data:`GAP`
    medians), every value finite and within :data:`ABSURD`, no duplicate or empty name, no signal that
    is zero or below 1 / :data:`ABSURD` throughout (it could not be scaled). ``lines``: each sample's
    line in the file ``what`` names, which the errors then give (else the sample's index)."""
    t = np.asarray(t, dtype=float).ravel()

    def at(i: int) -> str:
        return f"line {lines[i]}" if lines is not None else f"sample {i}"

    def pair(i: int) -> str:
        return f"lines {lines[i]} and {lines[i + 1]}" if lines is not None else f"samples {i + 1} and {i + 2}"

    if not signals:
        raise NsfemError(f"{what}: no sensor columns besides 't'")
    names = tuple(signals)
    if len(set(names)) != len(names) or any(not n for n in names) or "t" in names:
        raise NsfemError(f"{what}: sensor columns must have distinct non-empty names other than 't', got "
                         f"{', '.join(map(repr, names))}")
    if t.size < 2:
        raise NsfemError(f"{what}: needs at least two samples, got {t.size}")
    if not np.all(np.isfinite(t)):
        raise NsfemError(f"{what}: column 't' holds NaN or inf at {at(int(np.argmin(np.isfinite(t))))}")
    if np.max(np.abs(t)) > ABSURD:
        i = int(np.argmax(np.abs(t)))
        raise NsfemError(f"{what}: column 't', {at(i)}: t = {t[i]:g} s is beyond {ABSURD:g} s (a unit or export "
                         "error?)")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise NsfemError(f"{what}: column 't': t must increase, but t = {t[i]:g} s is followed by {t[i + 1]:g} s "
                         f"({pair(i)})")
    median = float(np.median(steps))
    tiny = steps < CLOSE * median
    if np.any(tiny):
        i = int(np.argmax(tiny))
        raise NsfemError(f"{what}: column 't': {pair(i)} lie {steps[i]:.3g} s apart, against a median step of "
                         f"{median:.3g} s (a duplicated or garbled time stamp? the runs would have to "
                         "output at that step)")
    gap = steps > GAP * median
    if np.any(gap):
        i = int(np.argmax(gap))
        raise NsfemError(f"{what}: column 't': {pair(i)} lie {steps[i]:.3g} s apart, {steps[i] / median:.3g} times "
                         f"the median step of {median:.3g} s (a gap in the record: the runs would simulate through "
                         "it; fit the pieces separately)")
    if t[0] < 0:
        raise NsfemError(f"{what}: column 't', {at(0)}: t starts at {t[0]:g} s; the scene's clock starts at 0 (its "
                         "[initial] state)")
    values = np.empty((t.size, len(names)))
    for j, name in enumerate(names):
        v = np.asarray(signals[name], dtype=float).ravel()
        if v.size != t.size:
            raise NsfemError(f"{what}: column {name!r} has {v.size} samples, 't' {t.size}")
        if not np.all(np.isfinite(v)):
            raise NsfemError(f"{what}: column {name!r} holds NaN or inf at {at(int(np.argmin(np.isfinite(v))))}")
        if not np.any(v):
            raise NsfemError(f"{what}: column {name!r} is zero throughout; a relative misfit needs a signal")
        big = int(np.argmax(np.abs(v)))
        if abs(v[big]) > ABSURD:
            raise NsfemError(f"{what}: column {name!r}, {at(big)}: {v[big]:g} m is beyond {ABSURD:g} m (a unit or "
                             "export error? the misfit would overflow)")
        if abs(v[big]) < 1.0 / ABSURD:
            raise NsfemError(f"{what}: column {name!r}: its largest magnitude, {abs(v[big]):.3g} m at {at(big)}, is "
                             f"below {1.0 / ABSURD:g} m (denormal or garbled values? a relative misfit divides by the "
                             "signal's RMS)")
        values[:, j] = v
    return Measurement(t, names, values, lines)


def match_sensors(m: Measurement, sensors, what: str = "data") -> list[int]:
    """Indices into the scene's ``sensors`` of the measurement's columns, in column order; a column
    that names no sensor is an error (the scene's other sensors are not fitted)."""
    index = {s.name: i for i, s in enumerate(sensors)}
    if not index:
        raise NsfemError(f"{what}: the scene has no [[sensor]]; add one per measured column")
    unknown = [n for n in m.names if n not in index]
    if unknown:
        raise NsfemError(f"{what}: column {unknown[0]!r} is no sensor of the scene (its sensors: "
                         f"{', '.join(index)})")
    return [index[n] for n in m.names]


def is_uniform(t: np.ndarray) -> bool:
    """Whether ``t`` is sampled at one step (to :data:`UNIFORM`)."""
    steps = np.diff(t)
    return bool(np.ptp(steps) <= UNIFORM * np.median(steps))


def spectra(values: np.ndarray) -> np.ndarray:
    """Amplitude spectra (columns) of uniformly sampled signals: |FFT| of the Hann-windowed samples,
    mean included (a static deflection is information too); a time shift leaves them nearly alone."""
    window = np.hanning(values.shape[0])[:, None]
    return np.abs(np.fft.rfft(values * window, axis=0)) * (2.0 / window.sum())


def transform(values: np.ndarray, kind: str) -> np.ndarray:
    """What the misfit compares: the samples (``time``) or their amplitude spectra (``spectrum``)."""
    if kind not in MISFITS:
        raise NsfemError(f"--misfit must be {' or '.join(MISFITS)}, got {kind!r}")
    return values if kind == "time" else spectra(values)


def scales(m: Measurement, kind: str) -> np.ndarray:
    """Per sensor, the RMS of the measured signal (or of its spectrum) that divides its residuals."""
    return np.sqrt(np.mean(transform(m.values, kind) ** 2, axis=0))


def residuals(simulated: np.ndarray, m: Measurement, kind: str, scale: np.ndarray | None = None) -> np.ndarray:
    """(simulated - measured) / scale per sensor, in the domain of ``kind``, flattened
    (sample-major); ``simulated`` is sampled at ``m.t`` like ``m.values``."""
    scale = scales(m, kind) if scale is None else scale
    return ((transform(simulated, kind) - transform(m.values, kind)) / scale).ravel()


def relative_rms(r: np.ndarray) -> float:
    """The RMS of relative residuals: the misfit (0.01 is 1 % of the measured RMS)."""
    return float(math.sqrt(np.mean(np.square(r)))) if r.size else math.nan


def sample(t_run: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A run's signals (len(t_run), s) at the measurement's times ``t``: a cubic spline through the
    outputs (exact where the run's output times hold the data's; the fit outputs :data:`nsfem.fit.problem.REFINE`
    times per data step otherwise)."""
    from scipy.interpolate import CubicSpline

    if t_run.size < 4:
        return np.column_stack([np.interp(t, t_run, values[:, j]) for j in range(values.shape[1])])
    return CubicSpline(t_run, values, axis=0)(t)
