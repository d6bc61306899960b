"""Bearing forces over time (``bearings.png`` of ``nsfem run``): one row per bearing with its forces on the
shaft along y and z (and x for a thrust bearing) of the inertial frame, drawn as the run (its envelope where
it is denser than the pixels) and its last periods (:func:`nsfem.plot.common.long_signal`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import dominant_period, figure, long_signal, save, zoom_panel, zoom_span

#: up to this many bearings get a row each; the rest are left to bearings.csv
MAX_ROWS = 6


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
    for r in range(rows):
        ax, zoom = axes[r, 0], None
        if span:
            ax, zoom = zoom_panel(ax, width=0.3)
        for k in index[index[:, 0] == r, 1]:
            name, colour = "xyz"[k], f"C{(k + 2) % 3}"
            long_signal(ax, t, forces[:, r, k], period=period, zoom=zoom, span=span, color=colour, label=f"F{name}")
        for a in (ax, zoom):
            if a is not None:
                a.set_ylabel(f"{names[r]} [N]")
                a.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        if r == rows - 1:
            for a in (ax, zoom):
                if a is not None:
                    a.set_xlabel("t [s]")
    more = f" (first {MAX_ROWS} of {len(names)}; all in bearings.csv)" if len(names) > MAX_ROWS else ""
    fig.suptitle(f"{title}\nbearing forces on the shaft, inertial frame{more}", fontsize=9)
    fig.tight_layout()
    return save(fig, path)


__all__ = ["bearings_plot"]
