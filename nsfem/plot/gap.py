"""gap.png: each contact part's gap over time: a delamination's middle gap, a crack's opening, a ring's
clearance, a stop's gap; closed intervals shaded, impacts marked, the counts of :mod:`nsfem.contact.tally`."""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from .common import columns, figure, long_signal, save
from .data import FIGSIZE, NoPlotData, _speed_hz, closed_intervals, delamination_middles

#: per kind of part: the panel's quantity and the figure's title
QUANTITY = {"delamination": "gap", "crack": "opening", "ring": "clearance", "stop": "gap"}
TITLES = {"delamination": "gap at the middle of the delamination", "crack": "crack opening",
          "ring": "stator ring clearance", "stop": "gap at the stop"}


def gap_plot(result, system, path) -> Path:
    """One panel per contact part (:func:`delamination_middles`):

    - a delamination: the gap at its middle (bold), its other contact points thin;
    - a crack: its opening, the larger gap of its front's two ends (drawn thin), shaded lighter where one
      end is closed;
    - a ring: its clearance, the smallest gap over its facets (the shaft's distance to the ring);
    - a stop: its gap;

    shaded where the part is closed (at least one of its points; for a crack both ends, one end lighter)
    and its impacts marked, with the counts and closed share of :func:`nsfem.contact.tally.tally` (the run
    JSON's ``parts``). Gaps in mm, or in um when a panel's largest is below 0.01 mm; a long run's lines
    are drawn as their envelope over each revolution (:func:`~nsfem.plot.common.long_signal`). Legends sit beside the
    panels."""
    from ..contact.tally import tally

    groups = delamination_middles(system)
    if not groups:
        raise NoPlotData("gap: the scene has no contacts")
    if result.t.size == 0:
        raise NoPlotData("gap: the run has no samples")
    t = result.t
    counts = tally(result, [g["part"] for g in groups])
    labels = list(system.model_contacts.labels)
    speed = _speed_hz(result, system)
    zoom = zoom_window(t, speed)
    long = zoom is not None   # more than ZOOM_AFTER revolutions: each drawn as its envelope, the zoom shows them
    if zoom and all(np.any(result.state[g["indices"]][:, t >= zoom[0]] != 0, axis=0).all() for g in groups):
        # closed throughout the last revolutions (a steady rub): nothing to see there; the first ones, where it
        # closed, instead (drawn over the whole run, seconds long, that closure is a line on the axis)
        zoom = (float(t[0]), zoom[1])
    inside = None if zoom is None else (t >= zoom[0]) if zoom[0] > t[0] else (t <= t[0] + zoom[1] / speed)
    fig, axes = figure(nrows=len(groups), ncols=1 + bool(zoom), sharex="col", squeeze=False, layout="constrained",
                       figsize=(FIGSIZE[0] + 2.6 + 2.4 * bool(zoom), max(FIGSIZE[1], 2.4 * len(groups))),
                       gridspec_kw={"width_ratios": [3, 1]} if zoom else None)
    for row, (g, pt) in enumerate(zip(groups, counts.parts)):
        ax = axes[row, 0]
        unit = _panel(ax, result, g, pt, labels, t, period=1.0 / speed if speed > 0 else None, long=long)
        a, b = g["span"]
        where = f"x = {a:.4g} to {b:.4g} m" if b > a else f"x = {g['x']:.4g} m"
        n = len(g["indices"])
        title = {"delamination": f"{g['name']} ({where}): gap at its middle",
                 "crack": f"{g['name']} ({where}): opening, the larger gap of its front's two ends",
                 "ring": f"{g['name']} ({where}): clearance, the smallest gap over its {n} facets",
                 "stop": f"{g['name']} ({where}): gap"}[g["kind"]]
        ax.set_title(title, fontsize=9)
        ax.set_ylabel(f"{QUANTITY[g['kind']]} [{unit}]")
        if zoom:
            zx = axes[row, 1]
            _panel(zx, result, g, pt, labels, t, inside)
            zx.set_ylabel(ax.get_ylabel())   # (its own scale: the numbers need their quantity too)
            zx.set_title(f"the {'last' if zoom[0] > t[0] else 'first'} {zoom[1]} revolutions", fontsize=9)
            zx.set_xlim(t[inside][0], t[inside][-1])
            zx.legend(*ax.get_legend_handles_labels(), fontsize=7.5, loc="upper left", bbox_to_anchor=(1.03, 1.0),
                      borderaxespad=0.0)
        else:
            ax.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    if zoom:
        axes[-1, 1].set_xlabel("time [s]")
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 0].set_xlim(t[0], t[-1])
    kinds = list(dict.fromkeys(g["kind"] for g in groups))
    head = "; ".join(TITLES[k] for k in kinds)
    fig.suptitle(head[0].upper() + head[1:], fontsize=10)
    return save(fig, path)


#: a long run's closed intervals are shaded on its main panel only when each gets this many pixel columns or more
SHADE_COLUMNS = 16
#: a run of more revolutions than this gets a zoom on its last ZOOM_REVOLUTIONS beside each panel (on its first ones
#: if every part is closed throughout the last)
ZOOM_AFTER, ZOOM_REVOLUTIONS = 30, 3


def zoom_window(t: np.ndarray, speed_hz: float) -> tuple[float, int] | None:
    """(start time, revolutions) of the zoom on the last revolutions of a run that holds more than
    :data:`ZOOM_AFTER` of them at ``speed_hz`` (and at least 8 samples in the zoom), else None."""
    if t.size < 2 or not speed_hz > 0 or (t[-1] - t[0]) * speed_hz <= ZOOM_AFTER:
        return None
    start = t[-1] - ZOOM_REVOLUTIONS / speed_hz
    return (float(start), ZOOM_REVOLUTIONS) if np.count_nonzero(t >= start) >= 8 else None


def _panel(ax, result, g: dict, pt, labels: list, t: np.ndarray, sel: np.ndarray | None = None,
           period: float | None = None, long: bool = False) -> str:
    """Draw one part's gap panel (see :func:`gap_plot`) on ``ax`` over the samples ``sel`` (default all), a
    signal denser than the pixels, or any of a ``long`` run, as its envelope over each ``period`` [s] (the
    rotation's: a gap oscillates several times a revolution); returns the unit of its axis."""
    draw = partial(long_signal, period=period, dense=True if long else None)
    kind, rows = g["kind"], g["indices"]
    sel = np.ones(t.size, bool) if sel is None else sel
    ts, gap = t[sel], result.gap[:, sel]
    peak = float(np.abs(result.gap[rows]).max(initial=0.0))
    scale, unit = (1e3, "mm") if peak >= 1e-5 or peak == 0.0 else (1e6, r"$\mu$m")
    wmin = 2e-3 * (ts[-1] - ts[0])  # closures often last far less than a pixel: widen them to one
    # a long run's closures closer than SHADE_COLUMNS pixel columns are a moire over the envelope: the zoom shows them
    shade = not (long and len(pt.spans) * SHADE_COLUMNS > columns(ax))
    if kind == "crack":
        for k in rows:
            draw(ax, ts, scale * gap[k], lw=0.5, color="0.65")
        ax.plot([], [], lw=0.5, color="0.65", label="front ends " + ", ".join(labels[k].rsplit(".", 1)[-1]
                                                                            for k in rows))
        draw(ax, ts, scale * gap[rows].max(axis=0), lw=1.3, color="tab:blue", label="opening (larger end gap)")
        if shade:
            _shade(ax, pt.spans, ts, wmin, color="tab:orange", alpha=0.2)
        spans = closed_intervals(result, rows)   # both ends
    elif kind == "delamination":
        if len(rows) > 1:
            for k in rows:
                if k != g["middle"]:
                    draw(ax, ts, scale * gap[k], lw=0.5, color="0.65")
            ax.plot([], [], lw=0.5, color="0.65", label="its other contact points")
        draw(ax, ts, scale * gap[g["middle"]], lw=1.3, color="tab:blue", label=f"middle, x = {g['x']:.4g} m")
        spans = pt.spans
    else:
        draw(ax, ts, scale * pt.gap[sel], lw=1.3, color="tab:blue",
             label=f"smallest of its {len(rows)} facets" if kind == "ring" else "gap")
        spans = pt.spans
    ax.axhline(0.0, color="k", lw=0.6)
    seen = _shade(ax, spans, ts, wmin, color="tab:red", alpha=0.3) if shade else []
    if seen:
        ax.hlines(np.zeros(len(seen)), [a for a, _ in seen], [b for _, b in seen], color="tab:red", lw=4,
                  capstyle="butt")
    share = f"{100 * pt.closed_fraction:.3g} % of the time"
    if kind == "crack":
        if pt.spans:
            ax.plot([], [], color="tab:orange", alpha=0.3, lw=6, label=f"closed, one end or both: {share}")
        if spans:
            ax.plot([], [], color="tab:red", alpha=0.5, lw=6, label=f"both ends closed ({len(spans)} intervals)")
    elif spans:
        ax.plot([], [], color="tab:red", alpha=0.5, lw=6,
                label=f"{'some point closed' if kind == 'delamination' else 'closed'}: {share}")
    if pt.impacts:
        hit = (pt.impact_t >= ts[0]) & (pt.impact_t <= ts[-1])
        ax.plot(pt.impact_t[hit], np.zeros(int(hit.sum())), "v", color="tab:red", ms=5,
                label=f"impacts ({pt.impacts}, largest {pt.max_impulse_Ns:.3g} N s)")
    ax.grid(True, alpha=0.3)
    return unit


def _shade(ax, spans, ts: np.ndarray, wmin: float, **kw) -> list[tuple[float, float]]:
    """Shade the closed intervals ``spans`` that meet the samples' span ``ts`` over the panel's height, as one
    collection (hundreds of intervals in a long run), each at least ``wmin`` wide; returns them."""
    seen = [(a, max(b, a + wmin)) for a, b in spans if b >= ts[0] and a <= ts[-1]]
    if seen:
        # behind the lines: a part closed most of the time would hide its gap
        ax.broken_barh([(a, b - a) for a, b in seen], (0.0, 1.0), transform=ax.get_xaxis_transform(), lw=0,
                       zorder=0.5, **kw)
    return seen
