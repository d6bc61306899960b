"""Campbell diagram: rotating-frame frequencies against speed, 1x line, resonances, bands."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save


def campbell_plot(path: str | Path, speeds_hz, open_hz, closed_hz=None, resonances=None, bands=(),
                  title: str = "") -> Path:
    """Write the diagram; ``resonances`` maps "open"/"closed" to gravity-resonance speeds."""
    fig, ax = figure(figsize=(7.0, 4.8))
    s = np.asarray(speeds_hz)
    top = float(s.max()) if len(s) else 1.0
    for lo, hi in bands:
        if lo < top:
            ax.axvspan(lo, min(hi, top), color="tab:red", alpha=0.08, lw=0)
    if bands:
        ax.plot([], [], color="tab:red", alpha=0.3, lw=6, label="divergence band (open)")
    for F, name in ((np.asarray(open_hz), "open"), (None if closed_hz is None else np.asarray(closed_hz), "closed")):
        if F is None:
            continue
        # points, not lines: frequencies are sorted per speed, and lines would jump between
        # modes where they cross or where a pair turns real (0 Hz) in a divergence band
        color = "tab:blue" if name == "open" else "tab:orange"
        ax.plot(np.repeat(s, F.shape[1]), F.ravel(), "." if name == "open" else "x", color=color,
                ms=3 if name == "open" else 3.5, mew=0.8, label=f"contacts {name}")
    ax.plot(s, s, ":", color="k", lw=1, label="1x (gravity forcing)")
    for name, marker, color in (("open", "o", "tab:blue"), ("closed", "s", "tab:orange")):
        r = np.asarray((resonances or {}).get(name, []))
        r = r[r <= top]
        if len(r):
            ax.plot(r, r, marker, color=color, mfc="none", ms=9, label=f"gravity resonance ({name})")
    ax.set_xlabel("rotation speed [Hz]")
    ax.set_ylabel("rotating-frame natural frequency [Hz]")
    ax.set_xlim(s.min(), top)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return save(fig, path)
