"""sensors.png: the probes' signals over the run and the last periods, their spectra, and the orbits where
two probes look at one x (with the clearance circle of a stator ring there)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .common import dominant_period, figure, label_row, long_signal, save, zoom_panel, zoom_span

#: an amplitude spectrum is drawn down to this fraction of its peak (6 decades: 12 of power, the PSD's range)
SPECTRUM_DECADES = 6
#: up to this many probes get a row of their own over time; more share one
MAX_ROWS = 6


def orbit_pairs(sensors) -> list[tuple[int, int]]:
    """(i, j): a y-probe and a z-probe at the same x in the same frame (an orbit)."""
    pairs = []
    for i, a in enumerate(sensors):
        for j, b in enumerate(sensors):
            if a.direction[1] == "y" and b.direction[1] == "z" and a.x == b.x and a.frame == b.frame:
                pairs.append((i, j))
    return pairs


def stator_rings(system) -> list[tuple[float, float]]:
    """(x [m], clearance [m]) of each stator ring of ``system``'s model (its facets, contacts with an angle,
    share one x and one clearance); empty without a model or rings. A ring is centred on the bearing axis,
    so its clearance circle is the same in the inertial and the rotating frame."""
    model = (getattr(system, "info", None) or {}).get("model")
    if model is None:
        return []
    rings: dict[str, tuple[float, float]] = {}
    for c in model.stack.contacts:
        if c.kind == "obstacle" and c.angle is not None:
            rings.setdefault(c.table_key, (float(c.x), float(c.clearance)))
    return list(rings.values())


def sensors_plot(path: str | Path, t: np.ndarray, values: np.ndarray, sensors, speed_hz: float = 0.0,
                 title: str = "", rings: Sequence[tuple[float, float]] = (), speed_at=None) -> Path:
    """Each signal against time in a row of its own (its own scale: a probe's static sag would flatten the
    others' vibration; more than :data:`MAX_ROWS` probes share one row), drawn as the run (its envelope where
    it is denser than the pixels) and the last periods (see :func:`nsfem.plot.common.long_signal`); their
    amplitude spectra over the last half (1x marked); one panel per orbit (y-probe against z-probe at one
    x, the last half drawn darker), with the clearance circle of each ring in ``rings`` [(x, clearance)]
    at that x (:func:`stator_rings`)."""
    t, values = np.asarray(t, dtype=float), np.asarray(values, dtype=float)
    pairs = orbit_pairs(sensors)
    ncols = 1 + len(pairs)
    rows = len(sensors) if 0 < len(sensors) <= MAX_ROWS else 1
    fig = figure(figsize=(max(8.4, 4.2 * ncols), 1.45 * rows + 4.6))[0]
    fig.axes[0].remove()
    height = fig.get_figheight()
    lines = -(-len(sensors) // 4)  # the legend's lines above the panels
    top = 1.0 - ((0.32 if title else 0.05) + 0.16 * lines + 0.38) / height
    bottom = 0.55 / height
    gap = 1.0  # inches between the time rows and the panels below: tick labels, a label, a two-line title
    avail = height * (top - bottom)
    outer = fig.add_gridspec(2, 1, height_ratios=[1.0 * rows, 2.4], hspace=2 * gap / (avail - gap),
                             left=0.8 / fig.get_figwidth(), right=1.0 - 0.3 / fig.get_figwidth(), bottom=bottom,
                             top=top)
    over_time = outer[0].subgridspec(rows, 1, hspace=0.12)
    below = outer[1].subgridspec(1, ncols, wspace=0.3)
    band = None
    if speed_at is not None:    # a run-up: the zoom's period at the end, the spectrum's 1x a band of speeds
        half = float(t[0] + 0.5 * (t[-1] - t[0]))
        band = (float(speed_at(half)), float(speed_at(float(t[-1]))))
        speed_hz = band[1]
    period = 1.0 / speed_hz if speed_hz > 0 else None
    if period is None and len(sensors):
        period = dominant_period(t, values[:, 0])
    span = zoom_span(t, period)
    colors = [f"C{k % 10}" for k in range(len(sensors))]
    handles, mains, zooms = [], [], []
    for r in range(rows):
        ax, zoom = fig.add_subplot(over_time[r]), None
        if span:
            ax, zoom = zoom_panel(ax, width=0.3)
        mains.append(ax)
        zooms.append(zoom)
        if r:
            ax.sharex(mains[0])
            if zoom is not None:
                zoom.sharex(zooms[0])
        for k in ([r] if rows > 1 else range(len(sensors))):
            s = sensors[k]
            handles += long_signal(ax, t, 1e6 * values[:, k], period=period, zoom=zoom, span=span,
                                   color=colors[k], label=f"{s.name} ({s.direction}, {s.frame}, x = {s.x:g} m)")
        name = sensors[r].name if rows > 1 else "displacement"
        label_row(ax, zoom, f"{name} [µm]", r == rows - 1)
    mains[0].set_xlim(t[0], t[-1])
    mains[0].set_title("the run" + (" (bands: envelopes)" if any(a.collections for a in mains) else "")
                       + ("; shaded: zoomed on the right" if span else ""), fontsize=8)
    for zoom in zooms[1:]:
        if zoom is not None:
            zoom.set_title("")
    fig.legend(handles, [h.get_label() for h in handles], loc="upper center",
               bbox_to_anchor=(0.5, 1.0 - (0.32 if title else 0.05) / height), ncol=min(len(sensors), 4),
               fontsize=7, frameon=False)
    _spectra(fig.add_subplot(below[0]), t, values, sensors, colors, speed_hz, band)
    for c, (i, j) in enumerate(pairs, start=1):
        _orbit(fig.add_subplot(below[c]), t, values, sensors[i], sensors[j], i, j, rings)
    if title:
        fig.suptitle(title, fontsize=10, y=1.0 - 0.08 / height, va="top")
    return save(fig, path)


def _spectra(ax, t, values, sensors, colors, speed_hz: float, band: tuple | None = None) -> None:
    """Amplitude spectra (Hann window) of the last half, down to 10^-SPECTRUM_DECADES of the peak; the 1x line at
    ``speed_hz``, or for a run-up the ``band`` of speeds (Hz) the last half sweeps."""
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    n = int(np.count_nonzero(half))
    if n < 8:
        ax.text(0.5, 0.5, "fewer than 8 samples in the last half: no spectrum", ha="center", va="center",
                transform=ax.transAxes, fontsize=8)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("amplitude [µm]")
        return
    dt = float(np.median(np.diff(t[half])))
    f = np.fft.rfftfreq(n, dt)
    window = np.hanning(n)
    peak = 0.0
    for k, s in enumerate(sensors):
        with np.errstate(over="ignore", invalid="ignore"):   # a diverged record: inf and NaN, drawn as gaps
            x = values[half, k] - values[half, k].mean()
            amp = 1e6 * 2 * np.abs(np.fft.rfft(x * window)) / window.sum()
        if np.isfinite(amp[1:]).any():
            peak = max(peak, float(np.nanmax(np.where(np.isfinite(amp[1:]), amp[1:], np.nan))))
        ax.semilogy(f[1:], np.maximum(amp[1:], 1e-300), lw=0.8, color=colors[k])
    top = max(band) if band is not None else speed_hz
    right = min(f[-1], 10 * top if top > 0 else f[-1])
    if band is not None and band[0] != band[1]:
        lo, hi = min(band), max(band)
        ax.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0)
        ax.annotate(f"1x = {band[0]:.4g} -> {band[1]:.4g} Hz", (hi, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(3, -10), textcoords="offset points", color="tab:red", fontsize=7)
    elif speed_hz > 0:
        ax.axvline(speed_hz, color="tab:red", ls=":", lw=0.9)
        ax.annotate(f"1x = {speed_hz:g} Hz", (speed_hz, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(3, -10), textcoords="offset points", color="tab:red", fontsize=7)
    ax.set_xlim(0, right)
    if peak > 0:
        ax.set_ylim(peak * 10.0 ** -SPECTRUM_DECADES, peak * 3.0)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("amplitude [µm]")
    ax.set_title(f"spectrum of the last half (Hann window, {f[1] - f[0]:.3g} Hz resolution)", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)


def _orbit(ax, t, values, sy, sz, i: int, j: int, rings) -> None:
    """The orbit of one (y, z) probe pair, the clearance circle of a ring at its x, equal scales."""
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    y = 1e6 * (-1.0 if sy.direction[0] == "-" else 1.0) * values[:, i]
    z = 1e6 * (-1.0 if sz.direction[0] == "-" else 1.0) * values[:, j]
    ax.plot(y, z, lw=0.5, color="tab:blue", alpha=0.35)
    ax.plot(y[half], z[half], lw=1.0, color="tab:blue")
    finish_orbit_axes(ax, sy, rings, f"orbit at x = {sy.x:g} m ({sy.frame}); dark: last half")


def finish_orbit_axes(ax, sy, rings, head: str) -> None:
    """An orbit panel's frame: the stator ring's clearance circle at the probe's x (dashed), equal scales, the axes
    named by the probe's frame in µm, the title ``head`` (plus the clearance)."""
    ring = [c for x, c in rings if math.isclose(x, sy.x, rel_tol=1e-9, abs_tol=1e-12)]
    if ring:
        a = np.linspace(0.0, 2.0 * np.pi, 361)
        ax.plot(1e6 * ring[0] * np.cos(a), 1e6 * ring[0] * np.sin(a), color="0.3", lw=1.0, ls="--", zorder=1.5)
        head += f"\ndashed: stator clearance {1e6 * ring[0]:.4g} µm"
    ax.set_aspect("equal", adjustable="datalim")
    inertial = sy.frame == "inertial"
    ax.set_xlabel(("y, horizontal" if inertial else "y (rotating)") + " [µm]")
    ax.set_ylabel(("z, vertical (up)" if inertial else "z (rotating)") + " [µm]")
    ax.set_title(head, fontsize=8)
    ax.grid(True, alpha=0.3)
