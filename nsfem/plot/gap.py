"""gap.png: each contact part's gap over time: a delamination's middle gap, a crack's opening, a ring's
clearance, a stop's gap; closed intervals shaded, impacts marked, the counts of :mod:`nsfem.contact.tally`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, closed_intervals, delamination_middles, draw_signal

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
    are drawn as their envelope (:func:`~nsfem.plot.data.min_max_bins`). Legends sit beside the panels."""
    from ..contact.tally import tally

    groups = delamination_middles(system)
    if not groups:
        raise NoPlotData("gap: the scene has no contacts")
    if result.t.size == 0:
        raise NoPlotData("gap: the run has no samples")
    t = result.t
    counts = tally(result, [g["part"] for g in groups])
    labels = list(system.model_contacts.labels)
    fig, axes = figure(nrows=len(groups), ncols=1, sharex=True, squeeze=False,
                       figsize=(FIGSIZE[0] + 2.6, max(FIGSIZE[1], 2.4 * len(groups))))
    wmin = 2e-3 * (t[-1] - t[0])  # closures often last far less than a pixel: widen them to one
    for ax, g, pt in zip(axes[:, 0], groups, counts.parts):
        kind, rows = g["kind"], g["indices"]
        peak = float(np.abs(result.gap[rows]).max(initial=0.0))
        scale, unit = (1e3, "mm") if peak >= 1e-5 or peak == 0.0 else (1e6, r"$\mu$m")
        if kind == "crack":
            for k in rows:
                draw_signal(ax, t, scale * result.gap[k], lw=0.5, color="0.65")
            ax.plot([], [], lw=0.5, color="0.65", label="front ends " + ", ".join(labels[k].rsplit(".", 1)[-1]
                                                                                for k in rows))
            draw_signal(ax, t, scale * result.gap[rows].max(axis=0), lw=1.3, color="tab:blue",
                        label="opening (larger end gap)")
            for a, b in pt.spans:
                ax.axvspan(a, max(b, a + wmin), color="tab:orange", alpha=0.2, lw=0)
            spans = closed_intervals(result, rows)   # both ends
            shaded = "both ends closed"
        elif kind == "delamination":
            if len(rows) > 1:
                for k in rows:
                    if k != g["middle"]:
                        draw_signal(ax, t, scale * result.gap[k], lw=0.5, color="0.65")
                ax.plot([], [], lw=0.5, color="0.65", label="its other contact points")
            draw_signal(ax, t, scale * result.gap[g["middle"]], lw=1.3, color="tab:blue",
                        label=f"middle, x = {g['x']:.4g} m")
            spans, shaded = pt.spans, "some point closed"
        else:
            draw_signal(ax, t, scale * pt.gap, lw=1.3, color="tab:blue",
                        label=f"smallest of its {len(rows)} facets" if kind == "ring" else "gap")
            spans, shaded = pt.spans, "closed"
        ax.axhline(0.0, color="k", lw=0.6)
        for a, b in spans:
            ax.axvspan(a, max(b, a + wmin), color="tab:red", alpha=0.3, lw=0)
            ax.plot([a, max(b, a + wmin)], [0.0, 0.0], color="tab:red", lw=4, solid_capstyle="butt")
        share = f"{100 * pt.closed_fraction:.3g} % of the time"
        if kind == "crack":
            if pt.spans:
                ax.plot([], [], color="tab:orange", alpha=0.3, lw=6, label=f"one end or both closed: {share}")
            if spans:
                ax.plot([], [], color="tab:red", alpha=0.5, lw=6, label=f"{shaded} ({len(spans)} intervals)")
        elif spans:
            ax.plot([], [], color="tab:red", alpha=0.5, lw=6, label=f"{shaded}: {share}")
        if pt.impacts:
            ax.plot(pt.impact_t, np.zeros(pt.impacts), "v", color="tab:red", ms=5,
                    label=f"impacts ({pt.impacts}, largest {pt.max_impulse_Ns:.3g} N s)")
        ax.set_ylabel(f"{QUANTITY[kind]} [{unit}]")
        a, b = g["span"]
        where = f"x = {a:.4g} to {b:.4g} m" if b > a else f"x = {g['x']:.4g} m"
        title = {"delamination": f"{g['name']} ({where}): gap at its middle",
                 "crack": f"{g['name']} ({where}): opening, the larger gap of its front's two ends",
                 "ring": f"{g['name']} ({where}): clearance, the smallest gap over its {len(rows)} facets",
                 "stop": f"{g['name']} ({where}): gap"}[kind]
        ax.set_title(title, fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 0].set_xlim(t[0], t[-1])
    kinds = list(dict.fromkeys(g["kind"] for g in groups))
    head = "; ".join(TITLES[k] for k in kinds)
    fig.suptitle(head[0].upper() + head[1:], fontsize=10)
    fig.tight_layout()
    return save(fig, path)
