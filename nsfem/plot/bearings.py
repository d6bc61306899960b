"""Bearing forces over time (``bearings.png`` of ``nsfem run``): one row per bearing with its forces on the
shaft along y and z (and x for a thrust bearing) of the inertial frame, drawn as the run (its envelope where
it is denser than the pixels) and its last periods (:func:`nsfem.plot.common.long_signal`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import dominant_period, figure, label_row, long_signal, save, zoom_panel, zoom_span

#: up to this many bearings get a row each; the rest are left to bearings.csv
MAX_ROWS = 6
#: a force whose largest value is below this share of the largest bearing force is drawn as zero
ROUND_OFF = 1e-9


def bearings_plot(path: str | Path, t: np.ndarray, forces: np.ndarray, names: list[str], index: np.ndarray,
                  speed_hz: float = 0.0, title: str = "") -> Path:
    """``forces`` (len(t), bearings, 3) [N] along (x, y, z); ``index`` the (bearing, axis) pairs to draw
    (:func:`nsfem.analysis.reactions.bearing_columns`)."""
    t, forces = np.asarray(t, dtype=float), np.asarray(forces, dtype=float)
    rows = max(1, min(MAX_ROWS, len(names)))
    fig, axes = figure(nrows=rows, ncols=1, figsize=(8.4, 1.9 * rows + 1.0), squeeze=False)
    period = 1.0 / speed_hz if speed_hz > 0 else None
    if period is None and t.size > 2:
        period = dominant_period(t, forces[:, index[0, 0], index[0, 1]]) if len(index) else None
    span = zoom_span(t, period)
    with np.errstate(invalid="ignore"):
        largest = float(np.nanmax(np.abs(forces), initial=0.0)) if forces.size else 0.0
    for r in range(rows):
        ax, zoom = axes[r, 0], None
        if span:
            ax, zoom = zoom_panel(ax, width=0.3)
        for k in index[index[:, 0] == r, 1]:
            name, colour = "xyz"[k], f"C{(k + 2) % 3}"
            f = forces[:, r, k]
            label = f"F{name}"
            # a force below ROUND_OFF of the largest is the solver's round-off (a thrust bearing without axial
            # load: 1e-11 N beside 170 N), not a signal: drawn as the zero it is, and said so
            if np.nanmax(np.abs(f), initial=0.0) < ROUND_OFF * largest:
                f, label = np.zeros_like(f), f"F{name} (round-off: 0)"
            long_signal(ax, t, f, period=period, zoom=zoom, span=span, color=colour, label=label)
        label_row(ax, zoom, f"{names[r]} force [N]", r == rows - 1)
        # above the panel, outside the data (the bands fill the axes)
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize=7, ncol=3, frameon=False,
                  borderaxespad=0.2)
    more = f" (first {MAX_ROWS} of {len(names)}; all in bearings.csv)" if len(names) > MAX_ROWS else ""
    fig.suptitle(f"{title}\nbearing forces on the shaft, inertial frame{more}", fontsize=9)
    fig.tight_layout()
    return save(fig, path)


__all__ = ["bearings_plot"]
