"""gap.png: each contact group's gap (a delamination's middle, a crack's opening, a ring's clearance) over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, closed_intervals, delamination_middles


def gap_plot(result, system, path) -> Path:
    """Gap over time at the middle of each delamination (bold), the other contacts of the
    delamination in thin lines, its closed intervals shaded and its impacts marked; for a crack
    its opening (bold: the larger gap of its front's two ends, drawn thin), shaded where it is
    closed (both ends) and, lighter, partly closed (one end). Gaps in mm, or in um when a panel's
    largest is below 0.01 mm."""
    groups = delamination_middles(system)
    if not groups:
        raise NoPlotData("gap: the scene has no contacts")
    if result.t.size == 0:
        raise NoPlotData("gap: the run has no samples")
    t = result.t
    impacts = result.impacts
    labels = list(system.model_contacts.labels)
    fig, axes = figure(nrows=len(groups), ncols=1, sharex=True, squeeze=False,
                       figsize=(FIGSIZE[0], max(FIGSIZE[1], 2.4 * len(groups))))
    wmin = 2e-3 * (t[-1] - t[0])  # closures often last far less than a pixel: widen them to one
    for ax, g in zip(axes[:, 0], groups):
        crack = g["kind"] == "crack"
        rows = g["indices"]
        peak = float(np.abs(result.gap[rows]).max(initial=0.0))
        scale, unit = (1e3, "mm") if peak >= 1e-5 or peak == 0.0 else (1e6, r"$\mu$m")
        for k in rows:
            if crack or k != g["middle"]:
                ax.plot(t, scale * result.gap[k], lw=0.5, color="0.65")
        if crack:
            ax.plot([], [], lw=0.5, color="0.65", label="front ends " + ", ".join(labels[k].rsplit(".", 1)[-1]
                                                                                for k in rows))
            ax.plot(t, scale * result.gap[rows].max(axis=0), lw=1.3, color="tab:blue", label="opening")
            partly = closed_intervals(result, rows, every=False)
            for a, b in partly:
                ax.axvspan(a, max(b, a + wmin), color="tab:orange", alpha=0.2, lw=0)
            if partly:
                ax.plot([], [], color="tab:orange", alpha=0.3, lw=6, label=f"one end or both closed ({len(partly)})")
            spans = closed_intervals(result, rows)
        else:
            if len(rows) > 1:
                ax.plot([], [], lw=0.5, color="0.65", label="other contacts")
            k = g["middle"]
            ax.plot(t, scale * result.gap[k], lw=1.3, color="tab:blue", label=f"x = {g['x']:.4g} m (middle)")
            spans = closed_intervals(result, k)
        ax.axhline(0.0, color="k", lw=0.6)
        for a, b in spans:
            ax.axvspan(a, max(b, a + wmin), color="tab:red", alpha=0.3, lw=0)
            ax.plot([a, max(b, a + wmin)], [0.0, 0.0], color="tab:red", lw=4, solid_capstyle="butt")
        if spans:
            ax.plot([], [], color="tab:red", alpha=0.5, lw=6,
                    label=f"{'both ends ' if crack else ''}closed ({len(spans)} intervals)")
        ti = [im["t"] for im in impacts if set(rows if crack else [g["middle"]]) & set(im.get("contacts", []))]
        if ti:
            ax.plot(ti, np.zeros(len(ti)), "v", color="tab:red", ms=5, label=f"impacts ({len(ti)})")
        ax.set_ylabel(f"{'opening' if crack else 'gap'} [{unit}]")
        a, b = g["span"]
        ax.set_title(f"{g['name']} (x = {g['x']:.4g} m): opening, the larger gap of its front's two ends" if crack
                     else f"{g['name']} ({a:.3g} to {b:.3g} m): gap at its middle", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 0].set_xlim(t[0], t[-1])
    cracks = sum(g["kind"] == "crack" for g in groups)
    fig.suptitle("Crack opening" if cracks == len(groups) else "Gap opening at the middle of the delamination"
                 + ("; crack opening" if cracks else ""), fontsize=10)
    fig.tight_layout()
    return save(fig, path)
