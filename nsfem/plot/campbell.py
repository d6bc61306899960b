"""Campbell diagram: frequencies against speed (rotating frame, or inertial-frame whirl), 1x line, resonances, bands."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save


def campbell_plot(path: str | Path, speeds_hz, open_hz, closed_hz=None, resonances=None, bands=(),
                  title: str = "", whirl=None) -> Path:
    """Write the diagram; ``resonances`` maps "open"/"closed" to gravity-resonance speeds (rotating
    frame) or critical speeds (inertial frame: ``whirl`` given, +1 forward / -1 backward per point)."""
    if whirl is not None:
        return _whirl_plot(path, np.asarray(speeds_hz), np.asarray(open_hz), np.asarray(whirl), resonances,
                           bands, title)
    s = np.asarray(speeds_hz)
    fig, ax, top = _axes(s, bands, "divergence band (open)")
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
    return _finish(fig, ax, s, top, "rotating-frame natural frequency [Hz]", title, path)


def _whirl_plot(path, s, F, W, resonances, bands, title) -> Path:
    """Inertial frame: whirl frequencies, forward and backward apart, the 1x line of the unbalance,
    critical speeds where it meets them, the bands where the rotor is unstable."""
    fig, ax, top = _axes(s, bands, "unstable")
    x = np.repeat(s, F.shape[1])
    for code, name, marker, color in ((1, "forward", "^", "tab:blue"), (-1, "backward", "v", "tab:orange"),
                                      (0, "at rest or planar", ".", "tab:gray"), (2, "axial", "s", "tab:green")):
        sel = W.ravel() == code
        if np.any(sel & np.isfinite(F.ravel())):
            ax.plot(x[sel], F.ravel()[sel], marker, color=color, ms=3, mew=0.6, mfc="none" if code == 2 else None,
                    label=f"{name} whirl" if code in (1, -1) else name)
    ax.plot(s, s, ":", color="k", lw=1, label="1x (unbalance forcing)")
    r = np.asarray((resonances or {}).get("open", []), dtype=float)
    r = r[r <= top]
    if len(r):
        ax.plot(r, r, "o", color="k", mfc="none", ms=9, label="critical speed")
    return _finish(fig, ax, s, top, "whirl frequency [Hz]", title, path)


def _axes(s: np.ndarray, bands, band_label: str):
    """(fig, ax, top): the diagram's axes with the speed bands shaded up to the last speed ``top``."""
    fig, ax = figure(figsize=(7.0, 4.8))
    top = float(s.max()) if len(s) else 1.0
    for lo, hi in bands:
        if lo < top:
            ax.axvspan(lo, min(hi, top), color="tab:red", alpha=0.08, lw=0)
    if bands:
        ax.plot([], [], color="tab:red", alpha=0.3, lw=6, label=band_label)
    return fig, ax, top


def _finish(fig, ax, s: np.ndarray, top: float, ylabel: str, title: str, path) -> Path:
    """Labels, limits, grid, legend and title; save."""
    ax.set_xlabel("rotation speed [Hz]")
    ax.set_ylabel(ylabel)
    ax.set_xlim(s.min(), top)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return save(fig, path)
