"""The resonance curve of a sweep: contact measures against the swept parameter.

Three panels against the first swept key: the share of time with a closed contact, the
smallest and largest gap, the largest normal force. A grid draws one curve per combination
of the other keys' values. Failed runs are left out (and counted in the title).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .common import figure, save


def plot_resonance(path: str | Path, keys: Sequence[str], points: Sequence[dict], runs: Sequence[dict | None],
                   title: str = "", dpi: int = 130, marks: dict | None = None,
                   bands: Sequence[tuple] = ()) -> Path:
    """Write the resonance-curve PNG of a sweep; returns its path.

    ``marks`` {label: [x, ...]} draws dotted vertical lines (e.g. gravity resonances),
    ``bands`` [(a, b), ...] shades intervals of the swept parameter (e.g. divergence bands).
    """
    fig, axes = figure(nrows=3, sharex=True, figsize=(7.0, 7.5))
    curves: dict[tuple, list[tuple[float, dict]]] = {}
    failed = 0
    for pt, row in zip(points, runs):
        if row is None:
            continue
        if row.get("error") or row.get("min_gap_m") is None:
            failed += bool(row.get("error"))
            continue
        curves.setdefault(tuple(pt[k] for k in keys[1:]), []).append((float(pt[keys[0]]), row))
    for label, pts in curves.items():
        pts.sort(key=lambda p: p[0])
        x = np.array([p[0] for p in pts])
        name = ", ".join(f"{k.split('.')[-1]}={v:g}" for k, v in zip(keys[1:], label)) or None
        closed = [100 * r["closed_fraction"] for _, r in pts]
        line, = axes[0].plot(x, closed, "o-", ms=3, label=name)
        axes[1].plot(x, [1e3 * r["max_gap_m"] for _, r in pts], "o-", ms=3, color=line.get_color())
        axes[1].plot(x, [1e3 * r["min_gap_m"] for _, r in pts], "s--", ms=3, color=line.get_color(), alpha=0.6)
        axes[2].plot(x, [r["max_normal_force_N"] for _, r in pts], "o-", ms=3, color=line.get_color())
    for ax in axes:
        for k, (a, b) in enumerate(bands):
            ax.axvspan(a, b, color="0.85", zorder=0, label="divergence band" if (ax is axes[0] and k == 0) else None)
        for j, (label, xs) in enumerate((marks or {}).items()):
            for i, x in enumerate(xs):
                ax.axvline(x, ls=":", color=f"C{3 + j}", lw=1, label=label if (ax is axes[0] and i == 0) else None)
    for ax in axes[1:]:  # gaps and forces span decades near divergence: linear below, log above
        ax.set_yscale("symlog", linthresh=1e-3 if ax is axes[1] else 1.0)
        ax.set_ylim(bottom=0.0)
    axes[0].set_ylabel("closed [% of time]")
    axes[1].set_ylabel("gap [mm]\nmax (—), min (--)")
    axes[2].set_ylabel("max normal force [N]")
    axes[2].set_xlabel(keys[0])
    for ax in axes:
        ax.grid(True, alpha=0.3)
    if any(k for k in curves if k) or marks or bands:
        axes[0].legend(fontsize=7)
    head = title + (f"\n{failed} failed run(s) not shown" if failed else "")
    axes[0].set_title(head, fontsize=9)
    fig.tight_layout()
    return save(fig, path, dpi)
