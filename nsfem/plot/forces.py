"""forces.png: each contact part's resultant force over time and its impact impulses (the numbers of
:mod:`nsfem.contact.tally`, as in the run JSON's ``parts``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, long_signal, save, zoom_panel, zoom_span
from .data import FIGSIZE, NoPlotData, _force_series, _speed_hz, loaded_contacts
from .gap import zoom_window

#: a part's friction force is drawn in its colour mixed with this share of white, opaque: over the part's normal
#: force (a band where it is dense) it stays in view
FRICTION_WHITE = 0.55


def lighter(color, white: float = FRICTION_WHITE) -> tuple:
    """``color`` mixed with ``white`` of white (RGB)."""
    from matplotlib.colors import to_rgb

    return tuple(1.0 - (1.0 - c) * (1.0 - white) for c in to_rgb(color))


def forces_plot(result, system, path) -> Path:
    """Per part that ever carries load or takes an impact (:func:`~nsfem.plot.data._force_series`), the
    magnitude of its resultant normal force [N] and, lighter, of its friction (tangential) force over time, for a ring
    the angle of its force, and its impacts as stems of its resultant impulse [N s]: a delamination's
    points and a crack's front ends summed, a ring's facets as a vector sum
    (:func:`nsfem.contact.tally.resultant`). One legend entry per part, beside the panels; a long run's
    forces (more than :data:`~nsfem.plot.gap.ZOOM_AFTER` revolutions) are drawn as their envelope over each
    revolution with their last revolutions beside them, a steady rub's first ones, as gap.png's
    (:func:`~nsfem.plot.common.long_signal`)."""
    from ..contact.tally import system_parts, tally

    if result.gap.shape[0] == 0:
        raise NoPlotData("forces: the scene has no contacts")
    rows = loaded_contacts(result)
    if not rows:
        raise NoPlotData("forces: no contact carried load or took an impact during the run")
    t = result.t
    speed = _speed_hz(result, system)
    period = 1.0 / speed if speed > 0 else None
    dense = True if zoom_window(t, speed) is not None else None   # a long run: its envelope per revolution
    series = _force_series(system, rows)
    shown = {tuple(ks) for _, ks in series}
    counts = tally(result, [p for p in system_parts(system) if tuple(p.rows) in shown])
    rings = [pt for pt in counts.parts if pt.angle is not None and pt.max_normal_force_N > 0]
    heights = [3] + [1.4] * bool(rings) + [2]
    fig, axes = figure(nrows=len(heights), ncols=1, sharex=True, squeeze=False, layout="constrained",
                       figsize=(FIGSIZE[0] + 2.6, FIGSIZE[1] + 1.4 * bool(rings)),
                       gridspec_kw={"height_ratios": heights})
    axes = list(axes[:, 0])
    ax, bx = axes[0], axes[-1]
    cx = axes[1] if rings else None
    # a long run: the forces' envelope per revolution and, beside it, its last revolutions as lines (a steady
    # rub's first)
    span = zoom_span(t, period) if dense else None
    if span is not None and all(np.any(result.state[list(pt.part.rows)][:, t >= span[0]] != 0, axis=0).all()
                                for pt in counts.parts):
        # closed throughout the last revolutions (a steady rub: a constant force there), as gap.png: the first ones,
        # where it closed, instead
        span = (float(t[0]), float(t[0]) + (span[1] - span[0]))
    zx = None
    if span is not None:
        ax, zx = zoom_panel(ax)
        ax.set_xlabel("time [s]")
        zx.set_xlabel("time [s]")
        zx.grid(True, alpha=0.3)
    colors = [f"C{i % 10}" for i in range(len(series))]
    friction = False
    for (_, _), pt, color in zip(series, counts.parts, colors):
        name = pt.part.name
        label = (f"{name}: max {pt.max_normal_force_N:.4g} N" if pt.max_normal_force_N > 0 else
                 f"{name}: no force (impacts only)")
        long_signal(ax, t, pt.force, period=period, dense=dense, zoom=zx, span=span, lw=1.0, color=color, label=label)
        if t.size <= 1400:   # closures shorter than output_dt show as single samples
            on = pt.force > 0
            ax.plot(t[on], pt.force[on], ".", ms=3, color=color)
        if np.any(pt.friction > 0):
            friction = True
            # lighter, as a line or as a band alike (a band has no dashes to tell it by)
            long_signal(ax, t, pt.friction, period=period, dense=dense, zoom=zx, span=span, lw=0.9,
                        color=lighter(color))
        if cx is not None and pt.angle is not None and pt.max_normal_force_N > 0:
            on = pt.force > 0
            cx.plot(t[on], np.degrees(pt.angle[on]), ".", ms=1.5, color=color)
    if friction:
        ax.plot([], [], color="k", lw=1.0, label="normal force: the part's colour")
        ax.plot([], [], color=lighter("k"), lw=3.0, label="friction force (tangential): lighter")
    ax.set_ylabel("force [N]" if friction else "normal force [N]")   # (no friction: no key to the two)
    if zx is not None:
        zx.set_ylabel(ax.get_ylabel())
    head = "Each part's resultant contact force (its points summed, a ring's facets as vectors)"
    if zx is None:
        ax.set_title(head, fontsize=9)
    else:   # the main panel is too narrow for it
        fig.suptitle(head, fontsize=9)
    ax.grid(True, alpha=0.3)
    (zx or ax).legend(*ax.get_legend_handles_labels(), fontsize=7.5, loc="upper left",
                      bbox_to_anchor=(1.03 if zx else 1.01, 1.0), borderaxespad=0.0)
    if t.size:
        ax.set_xlim(t[0], t[-1])
    if cx is not None:
        cx.set_ylabel("angle [deg]")
        cx.set_ylim(-180, 180)
        cx.set_yticks([-180, -90, 0, 90, 180])
        cx.set_title("direction of the ring's normal force while loaded (from +y towards +z)", fontsize=9)
        cx.grid(True, alpha=0.3)
    for pt, color in zip(counts.parts, colors):
        if pt.impacts:
            ml, sl, _ = bx.stem(pt.impact_t, pt.impact_Ns, basefmt=" ", label=f"{pt.part.name}: {pt.impacts} impacts")
            ml.set_color(color)
            ml.set_markersize(3.5)
            sl.set_color(color)
            sl.set_linewidth(0.8)
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_ylabel("impulse [N s]")
    bx.set_xlabel("time [s]")
    shared = f", {counts.shared_impacts} of them on more than one part at once" if counts.shared_impacts else ""
    bx.set_title(f"Impacts: {counts.impacts}{shared}, largest impulse {max(p.max_impulse_Ns for p in counts.parts):.3g}"
                 " N s (each part's resultant)" if counts.impacts else "no impacts", fontsize=9)
    bx.grid(True, alpha=0.3)
    if counts.impacts:
        bx.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    if t.size:
        bx.set_xlim(t[0], t[-1])
    return save(fig, path)
