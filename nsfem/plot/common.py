"""Shared plotting helpers: an off-screen figure, an atomic save, and long signals drawn so they read.

Figures are made on matplotlib's Agg canvas directly (no pyplot: no backend to select, no global
figure list to close) at the resolution they are saved with, so that the text extents measured by
``fig.tight_layout()`` are those the saved picture is drawn with and are measured once (a figure drawn
at another resolution than it was laid out in measures every label again: 10-20 % of a plot's time).

A run of several seconds sampled every 0.1 ms has 10^4..10^5 samples and hundreds of periods: drawn as a
line it is a solid block. :func:`long_signal` draws such a signal as its envelope (the smallest and largest
value in each pixel column of the axes, filled) and, on a second axes, the last few periods as a line;
:func:`zoom_panel` splits an axes into that pair and :func:`zoom_span` picks the periods.

>>> import numpy as np
>>> t = np.linspace(0.0, 8.0, 80001); y = np.sin(2 * np.pi * 50 * t)
>>> tc, lo, hi = envelope(t, y, 400)
>>> tc.size, bool(lo.max() < -0.99 and hi.min() > 0.99)
(400, True)
>>> zoom_span(t, period=1 / 50)
(7.9, 8.0)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import write_atomic

#: the resolution PNGs are saved at (:func:`save`), and so the pixel columns an envelope bins into
DPI = 130
#: a signal with more samples than this many per pixel column of its axes is drawn as its envelope
SAMPLES_PER_COLUMN = 2
#: a periodic signal with fewer pixel columns than this per period is drawn as its envelope (a sine drawn
#: in fewer reads as a blur of crossing lines)
PIXELS_PER_PERIOD = 8
#: how many periods the zoom panel of :func:`zoom_span` shows
ZOOM_PERIODS = 5
#: the keywords of ``figure`` that lay out the axes (``Figure.subplots``); the others make the figure
SUBPLOT_KEYS = ("nrows", "ncols", "sharex", "sharey", "squeeze", "width_ratios", "height_ratios", "subplot_kw",
                "gridspec_kw")


def figure(**kw):
    """(figure, axes) like ``pyplot.subplots(**kw)``, on the Agg canvas (no display needed) at :data:`DPI`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    grid = {k: kw.pop(k) for k in SUBPLOT_KEYS if k in kw}
    fig = Figure(**{"dpi": DPI, **kw})
    FigureCanvasAgg(fig)
    return fig, fig.subplots(**grid)


def save(fig, path: str | Path, dpi: int = DPI) -> Path:
    """Save ``fig`` as PNG through a temporary file and a rename.

    A figure with a layout engine (``layout="constrained"``, or the placeholder ``fig.tight_layout()``
    leaves) is laid out here once and saved without it: ``savefig`` would otherwise draw the whole
    figure a first time without rendering, only to run the engine (phase.png: 0.04 s of a 0.17 s save)."""
    _lay_out(fig, dpi)
    # zlib level 1 instead of PIL's 6: the shipped run's four PNGs encode in ~0.03 s instead of ~0.11 s of its
    # ~1.6 s (studies/latency.py), for files within about -10..+30 % of the size (line plots compress well)
    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png", pil_kwargs={"compress_level": 1}))


def _lay_out(fig, dpi: float) -> None:
    """Run ``fig``'s layout engine, if any, at the resolution ``dpi`` it is saved with (as ``savefig`` would),
    and remove it (the positions stay as it set them)."""
    import matplotlib
    from matplotlib.layout_engine import PlaceHolderLayoutEngine

    engine = fig.get_layout_engine()
    if engine is None:
        return
    if not isinstance(engine, PlaceHolderLayoutEngine):   # a placeholder: tight_layout has been applied
        shown = fig.dpi
        if dpi != shown:
            fig.dpi = dpi
        try:
            engine.execute(fig)
        finally:
            if fig.dpi != shown:
                fig.dpi = shown
    # None means "no engine" only while the rcParams name no default layout
    with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)


# --------------------------------------------------------------------------- long signals
def envelope(t: np.ndarray, y: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_c, lo, hi): the smallest and largest ``y`` in each of ``bins`` equal time bins of [t[0], t[-1]]
    (``t`` ascending), at the middle time of the samples in the bin; empty bins are left out, NaNs ignored.
    Drawn as a band, this is exactly what a line through every sample would cover at that resolution."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.size == 0:
        return t, y, y
    bins = max(1, int(bins))
    inner = np.linspace(t[0], t[-1], bins + 1)[1:-1]
    starts = np.unique(np.r_[0, np.searchsorted(t, inner, side="left")])
    starts = starts[starts < t.size]
    ends = np.r_[starts[1:], t.size] - 1
    with np.errstate(invalid="ignore"):
        lo = np.fmin.reduceat(y, starts)
        hi = np.fmax.reduceat(y, starts)
    return 0.5 * (t[starts] + t[ends]), lo, hi


def columns(ax) -> int:
    """The pixel columns ``ax`` spans in the saved PNG (at :data:`DPI`)."""
    fig = ax.figure
    return max(16, int(round(ax.get_position().width * fig.get_figwidth() * DPI)))


def zoom_span(t: np.ndarray, period: float | None = None, y: np.ndarray | None = None,
              periods: int = ZOOM_PERIODS) -> tuple[float, float] | None:
    """(t_a, t_b): the last ``periods`` periods of the record ``t``, or None when the whole record is not
    longer than four times that (it reads as it is). The period is ``period`` [s] (e.g. of the rotation),
    else that of the largest peak of ``y``'s spectrum over the last half (mean removed), else None."""
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        return None
    if not (period and period > 0) and y is not None:
        period = dominant_period(t, np.asarray(y, dtype=float))
    if not (period and period > 0):
        return None
    length = periods * float(period)
    if t[-1] - t[0] <= 4.0 * length:
        return None
    return float(t[-1] - length), float(t[-1])


def dominant_period(t: np.ndarray, y: np.ndarray) -> float | None:
    """1 / the frequency of the largest peak of the amplitude spectrum of ``y`` (mean removed, Hann window)
    over the last half of the record, or None for a constant or not finite one."""
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    if np.count_nonzero(half) < 8:
        return None
    th, yh = t[half], y[half]
    dt = float(np.median(np.diff(th)))
    if not dt > 0:
        return None
    yh = np.interp(np.arange(th[0], th[-1], dt), th, yh) if th.size > 1 else yh
    if yh.size < 8 or not np.all(np.isfinite(yh)):
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        a = np.abs(np.fft.rfft((yh - yh.mean()) * np.hanning(yh.size)))
    if a.size < 2 or not a[1:].max() > 0 or not np.isfinite(a).all():
        return None
    return 1.0 / np.fft.rfftfreq(yh.size, dt)[1 + int(np.argmax(a[1:]))]


def zoom_panel(ax, width: float = 0.32):
    """(main, zoom): ``ax`` replaced by two axes side by side in its place, the right one ``width`` of it
    (for :func:`long_signal`'s ``zoom``); ``ax`` is removed."""
    fig = ax.figure
    spec = ax.get_subplotspec().subgridspec(1, 2, width_ratios=[1.0 - width, width], wspace=0.28)
    ax.remove()
    return fig.add_subplot(spec[0]), fig.add_subplot(spec[1])


def label_row(ax, zoom, ylabel: str, last: bool) -> None:
    """Label one row of stacked time panels (``ax`` and its ``zoom``, or None): ``ylabel``, a grid, and the
    shared time axis numbered and named under the ``last`` row only."""
    for a in (ax, zoom):
        if a is None:
            continue
        a.set_ylabel(ylabel)
        a.grid(True, alpha=0.3)
        if last:
            a.set_xlabel("time [s]")
        else:
            a.tick_params(labelbottom=False)


def long_signal(ax, t: np.ndarray, y: np.ndarray, *, period: float | None = None, zoom=None,
                span: tuple[float, float] | None = None, color=None, label: str | None = None, lw: float = 0.8,
                dense: bool | None = None, **line_kw) -> list:
    """Draw the signal ``y(t)`` on ``ax`` so that it reads at the size it is drawn.

    With a ``period`` [s] (e.g. of the rotation): as a line while every period gets at least
    :data:`PIXELS_PER_PERIOD` pixel columns of ``ax``, else as its :func:`envelope` over bins of one period
    (the band the vibration fills, its amplitude's course readable; bins shorter than a period would beat
    against it). Without: as a line while it has at most :data:`SAMPLES_PER_COLUMN` samples per pixel
    column, else as its envelope per pixel column. The envelope is a band edged in ``color`` (and the line
    style ``ls``). ``dense`` True asks for the envelope whenever there are more samples than bins (a signal
    with several oscillations a period, e.g. a contact's gap, is a solid block at 8 columns a period).

    With a ``zoom`` axes and a ``span`` (see :func:`zoom_span`; one that starts at ``t[0]`` is titled "first"
    instead of "last"), the samples in ``span`` are drawn on
    ``zoom`` as a line too, and the span is shaded on ``ax``. Returns the artists drawn on ``ax`` (the first
    carries ``label``, for a legend)."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    cols = columns(ax)
    duration = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if period and period > 0:
        per = duration / period   # (capped: a 1e308 Hz scene's periods overflow; NaN: no bins)
        bins = int(per) if per < t.size else t.size   # at least as many bins as samples: a line
        crowded = bins * PIXELS_PER_PERIOD > cols
    else:
        bins = cols
        crowded = t.size > SAMPLES_PER_COLUMN * cols
    dense = (crowded if dense is None else dense) and t.size > max(bins, 1)
    if not dense:
        drawn = ax.plot(t, y, lw=lw, color=color, label=label, **line_kw)
        color = drawn[0].get_color()
    else:
        from matplotlib.colors import to_rgba

        if color is None:  # the next colour of the axes' cycle, as a line would take
            color = ax.plot([], [])[0].get_color()
        tc, lo, hi = envelope(t, y, bins)
        drawn = [ax.fill_between(tc, lo, hi, facecolor=to_rgba(color, 0.35), edgecolor=color, lw=0.5 * lw,
                                 linestyle=line_kw.get("ls", line_kw.get("linestyle", "-")), label=label)]
    if zoom is not None and span is not None:
        a, b = span
        sel = (t >= a) & (t <= b)
        zoom.plot(t[sel], y[sel], lw=lw, color=color, **line_kw)
        zoom.set_xlim(a, b)
        if not getattr(ax, "_nsfem_zoom_marked", False):
            ax.axvspan(a, b, color="0.5", alpha=0.15, lw=0, zorder=0)
            ax._nsfem_zoom_marked = True
            zoom.set_title(f"{'first' if t.size and a <= t[0] else 'last'} {b - a:.3g} s", fontsize=8)
    return drawn


# --------------------------------------------------------------------------- axis labels of scene keys
#: "quantity [unit]" of the scene keys a sweep or a fit varies most ("*": a list item's index); a
#: dimensionless quantity is marked [-]
KEY_LABELS = {
    "rotation.speed_hz": "rotor speed [Hz]",
    "rotation.gravity": "gravity [m/s²]",
    "rotation.phase_deg": "angle of the rotating frame at t = 0 [deg]",
    "damping.external": "external damping [N s/m²]",
    "shaft.E": "Young's modulus [Pa]",
    "shaft.rho": "shaft density [kg/m³]",
    "shaft.length": "shaft length [m]",
    "shaft.diameter": "shaft diameter [m]",
    "simulation.t_end": "simulated time [s]",
}
#: the same for the keys of a list item (``stator.0.clearance``), named after the item
ITEM_LABELS = {
    "clearance": "clearance [m]",
    "friction": "friction coefficient [-]",
    "restitution": "restitution coefficient [-]",
    "stiffness": "stiffness [N/m]",
    "damping": "damping [N s/m]",
    "magnitude": "unbalance [kg m]",
    "mass": "mass [kg]",
    "x": "position x [m]",
    "phase_deg": "angle [deg]",
    "polar_inertia": "polar inertia [kg m²]",
    "diametral_inertia": "diametral inertia [kg m²]",
}


def key_label(key: str) -> str:
    """An axis label "quantity [unit]" for the scene key ``key`` (``rotation.speed_hz`` -> "rotor speed
    [Hz]", ``stator.0.friction`` -> "stator.0 friction coefficient [-]", a bearing's ``kyz`` -> "... k_yz
    [N/m]"); else the key with the unit its schema entry gives ("shaft.width [m]"); else the key itself."""
    import re

    parts = key.split(".")
    generic = ".".join("*" if p.isdigit() else p for p in parts)
    if generic in KEY_LABELS:
        return KEY_LABELS[generic]
    if len(parts) == 3 and parts[1].isdigit():
        item, last = f"{parts[0]}.{parts[1]}", parts[2]
        m = re.fullmatch(r"([kc])([xyz])([xyz])", last)
        if m:
            what, unit = ("stiffness", "N/m") if m[1] == "k" else ("damping", "N s/m")
            return f"{item} {what} {m[1]}_{m[2]}{m[3]} [{unit}]"
        if last in ITEM_LABELS:
            return f"{item} {ITEM_LABELS[last]}"
    unit = _schema_unit(parts)
    return f"{key} [{unit}]" if unit else key


def _schema_unit(parts: list[str]) -> str | None:
    """The unit in brackets of the schema's description of the key ``parts``, if it names one."""
    import re

    from ..scene.schema import SCHEMA

    node = SCHEMA
    for p in parts:
        if isinstance(node, list) and p.isdigit():
            node = node[0]
        elif isinstance(node, dict) and p in node:
            node = node[p]
        else:
            return None
    m = re.search(r"\[([^\]]+)\]", getattr(node, "doc", "") or "")
    return m[1] if m else None
