"""The resonance curve of a sweep: contact measures against the swept parameter.

Three panels against the first swept key: the share of time with a closed contact, the
smallest and largest gap, the largest normal force; with sensors, a panel of their steady
amplitudes (a rotor without contacts has that panel alone: its unbalance response curve). A grid
draws one curve per combination of the other keys' values. Failed runs are left out (and counted
in the title).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .common import figure, key_label, save


def plot_resonance(path: str | Path, keys: Sequence[str], points: Sequence[dict], runs: Sequence[dict | None],
                   title: str = "", dpi: int = 130, marks: dict | None = None,
                   bands: Sequence[tuple] = ()) -> Path:
    """Write the resonance-curve PNG of a sweep; returns its path.

    ``marks`` {label: [x, ...]} draws dotted vertical lines (e.g. gravity resonances),
    ``bands`` [(a, b), ...] shades intervals of the swept parameter (e.g. divergence bands).
    """
    amp_keys = sorted({k for r in runs if r for k in r if k.startswith("amplitude_") and k.endswith("_m")})
    contacts = any(r is not None and not r.get("error") and r.get("min_gap_m") is not None for r in runs)
    nrows = (3 if contacts or not amp_keys else 0) + (1 if amp_keys else 0)
    fig, axes = figure(nrows=nrows, sharex=True, figsize=(7.0, 2.5 * nrows + 0.5), squeeze=False)
    axes = list(axes.ravel())
    amp_ax = axes.pop() if amp_keys else None
    curves: dict[tuple, list[tuple[float, dict]]] = {}
    failed = 0
    for pt, row in zip(points, runs):
        if row is None:
            continue
        if row.get("error") or (row.get("min_gap_m") is None and not amp_keys):
            failed += bool(row.get("error"))
            continue
        curves.setdefault(tuple(pt[k] for k in keys[1:]), []).append((float(pt[keys[0]]), row))
    for label, pts in curves.items():
        pts.sort(key=lambda p: p[0])
        x = np.array([p[0] for p in pts])
        name = ", ".join(f"{k.split('.')[-1]}={v:g}" for k, v in zip(keys[1:], label)) or None
        color = None
        if axes:
            closed = [100 * r["closed_fraction"] for _, r in pts]
            line, = axes[0].plot(x, closed, "o-", ms=3, label=name)
            color = line.get_color()
            axes[1].plot(x, [1e3 * r["max_gap_m"] for _, r in pts], "o-", ms=3, color=color)
            axes[1].plot(x, [1e3 * r["min_gap_m"] for _, r in pts], "s--", ms=3, color=color, alpha=0.6)
            axes[2].plot(x, [r["max_normal_force_N"] for _, r in pts], "o-", ms=3, color=color)
        if amp_ax is not None:
            for j, k in enumerate(amp_keys):
                # one curve per probe: its own colour unless the colours tell the other keys' values apart;
                # the later probes' markers hollow, so that equal amplitudes (a circular orbit) show both
                amp_ax.plot(x, [1e6 * r[k] if r.get(k) is not None else np.nan for _, r in pts],
                            ["o-", "s--", "^-.", "v:"][j % 4], ms=3 if j == 0 else 5, mfc=None if j == 0 else "none",
                            color=color if len(curves) > 1 else f"C{j % 10}",
                            label=f"{k[len('amplitude_'):-2]}" + (f" ({name})" if name else ""))
    every = axes + ([amp_ax] if amp_ax is not None else [])
    for ax in every:
        for k, (a, b) in enumerate(bands):
            ax.axvspan(a, b, color="0.85", zorder=0, label="divergence band" if (ax is every[0] and k == 0) else None)
        for j, (label, xs) in enumerate((marks or {}).items()):
            for i, x in enumerate(xs):
                ax.axvline(x, ls=":", color=f"C{3 + j}", lw=1, label=label if (ax is every[0] and i == 0) else None)
    if axes:
        for ax in axes[1:]:  # gaps and forces span decades near divergence: linear below, log above
            ax.set_yscale("symlog", linthresh=1e-3 if ax is axes[1] else 1.0)
            ax.set_ylim(bottom=0.0)
        axes[0].set_ylabel("closed [% of time]")
        axes[1].set_ylabel("gap [mm]\nmax (—), min (--)")
        axes[2].set_ylabel("max normal force [N]")
        if any(k for k in curves if k) or marks or bands:
            axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    if amp_ax is not None:
        _amplitude_scale(amp_ax)
        amp_ax.set_ylabel("sensor 1x amplitude [µm]\n(fitted, last half of each run)")
        amp_ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    every[-1].set_xlabel(key_label(keys[0]))
    for ax in every:
        ax.grid(True, alpha=0.3)
    head = title + (f"\n{failed} failed run(s) not shown" if failed else "")
    every[0].set_title(head, fontsize=9)
    fig.tight_layout()
    return save(fig, path, dpi)


#: amplitudes spanning less than this ratio are drawn on a linear axis (a log axis over less than two decades may
#: have a single labelled decade, and its minor labels read as "3 x 10^1, 4 x 10^1"); over more, two decades at least
LOG_RATIO = 100.0


def _amplitude_scale(ax) -> None:
    """A log axis for amplitudes over more than :data:`LOG_RATIO` (a resonance peak over decades), its labels
    plain numbers at the decades; else a linear one from 0."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    y = np.concatenate([np.asarray(line.get_ydata(), dtype=float) for line in ax.lines] or [np.zeros(0)])
    y = y[np.isfinite(y) & (y > 0)]
    if y.size and y.max() > LOG_RATIO * y.min():
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
    else:
        ax.set_ylim(bottom=0.0, top=1.08 * float(y.max()) if y.size else None)
