"""forces.png: contact forces over time and the impact impulses."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, _force_series, loaded_contacts


def forces_plot(result, system, path) -> Path:
    """Normal and tangential contact-force magnitudes [N] over time of the contacts that
    ever carry load, and the impacts as stems of their impulses [N s]. A crack's front ends
    are one line: the force across its faces (their normal forces summed, and impulses per
    impact)."""
    if result.gap.shape[0] == 0:
        raise NoPlotData("forces: the scene has no contacts")
    rows = loaded_contacts(result)
    if not rows:
        raise NoPlotData("forces: no contact carried load or took an impact during the run")
    t = result.t
    series = _force_series(system, rows)
    fig, (ax, bx) = figure(nrows=2, ncols=1, sharex=True, figsize=FIGSIZE, gridspec_kw={"height_ratios": [3, 2]})
    colors = [f"C{i % 10}" for i in range(len(series))]
    friction = False
    for (name, ks), color in zip(series, colors):
        normal = result.normal_force[ks].sum(axis=0)
        ax.plot(t, normal, lw=1.0, color=color, label=name)
        on = normal > 0  # closures shorter than output_dt show as single samples
        ax.plot(t[on], normal[on], ".", ms=4, color=color)
        tg = np.linalg.norm(result.tangential_force[ks], axis=1).sum(axis=0)
        if np.any(tg > 0):
            friction = True
            ax.plot(t, tg, lw=0.9, ls="--", color=color)
    if friction:
        ax.plot([], [], ls="--", color="k", lw=0.9, label="tangential |lam_T|")
    ax.set_ylabel("contact force [N]")
    ax.set_title("Normal force (solid)" + (" and tangential force magnitude (dashed)" if friction else "")
                 + " at the output times", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2 if len(series) > 4 else 1)
    n_imp = 0
    for (_, ks), color in zip(series, colors):
        ti, pi = [], []
        for im in result.impacts:
            mine = [p for c, p in zip(im.get("contacts", []), im.get("impulse_Ns", [])) if int(c) in ks]
            if mine:
                ti.append(im["t"])
                pi.append(sum(mine))
        if ti:
            n_imp += len(ti)
            ml, sl, bl = bx.stem(ti, pi, basefmt=" ")
            ml.set_color(color)
            ml.set_markersize(4)
            sl.set_color(color)
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_ylabel("impulse [N s]")
    bx.set_xlabel("time [s]")
    bx.set_title(f"Impacts: {n_imp} impulses" if n_imp else "no impacts", fontsize=9)
    bx.grid(True, alpha=0.3)
    if t.size:
        bx.set_xlim(t[0], t[-1])
    fig.tight_layout()
    return save(fig, path)

