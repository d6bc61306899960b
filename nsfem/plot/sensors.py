"""Sensor plots: time signals, their spectra, and orbits where two probes look at one x."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save


def orbit_pairs(sensors) -> list[tuple[int, int]]:
    """(i, j): a y-probe and a z-probe at the same x in the same frame (an orbit)."""
    pairs = []
    for i, a in enumerate(sensors):
        for j, b in enumerate(sensors):
            if a.direction[1] == "y" and b.direction[1] == "z" and a.x == b.x and a.frame == b.frame:
                pairs.append((i, j))
    return pairs


def sensors_plot(path: str | Path, t: np.ndarray, values: np.ndarray, sensors, speed_hz: float = 0.0,
                 title: str = "") -> Path:
    """Signals against time, their amplitude spectra over the last half (1x marked), and each orbit
    (y-probe against z-probe at one x; the last half drawn darker)."""
    pairs = orbit_pairs(sensors)
    ncols = 3 if pairs else 2
    fig, axes = figure(figsize=(4.2 * ncols, 4.2), ncols=ncols)
    ax_t, ax_f = axes[0], axes[1]
    for k, s in enumerate(sensors):
        ax_t.plot(t, 1e6 * values[:, k], lw=0.8, label=f"{s.name} ({s.direction}, {s.frame}, x = {s.x:g} m)")
    ax_t.set_xlabel("time [s]")
    ax_t.set_ylabel("displacement [um]")
    ax_t.grid(True, alpha=0.3)
    ax_t.legend(fontsize=7, loc="upper right")
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    if np.count_nonzero(half) >= 8:
        dt = float(np.median(np.diff(t[half])))
        n = int(np.count_nonzero(half))
        f = np.fft.rfftfreq(n, dt)
        window = np.hanning(n)
        for k, s in enumerate(sensors):
            x = values[half, k] - values[half, k].mean()
            amp = 2 * np.abs(np.fft.rfft(x * window)) / window.sum()
            ax_f.semilogy(f[1:], 1e6 * np.maximum(amp[1:], 1e-30), lw=0.8, label=s.name)
        if speed_hz > 0:
            ax_f.axvline(speed_hz, color="tab:red", ls=":", lw=0.9, label=f"1x = {speed_hz:g} Hz")
        top = min(f[-1], 10 * speed_hz if speed_hz > 0 else f[-1])
        ax_f.set_xlim(0, top)
        ax_f.set_xlabel("frequency [Hz]")
        ax_f.set_ylabel("amplitude [um] (Hann, last half)")
        ax_f.grid(True, which="both", alpha=0.3)
        ax_f.legend(fontsize=7, loc="upper right")
    if pairs:
        ax_o = axes[2]
        for i, j in pairs:
            sy = -1.0 if sensors[i].direction[0] == "-" else 1.0
            sz = -1.0 if sensors[j].direction[0] == "-" else 1.0
            y, z = 1e6 * sy * values[:, i], 1e6 * sz * values[:, j]
            ax_o.plot(y, z, lw=0.5, alpha=0.4)
            ax_o.plot(y[half], z[half], lw=1.0, label=f"x = {sensors[i].x:g} m ({sensors[i].frame})")
        ax_o.set_aspect("equal", adjustable="datalim")
        ax_o.set_xlabel("y [um]")
        ax_o.set_ylabel("z [um]")
        ax_o.grid(True, alpha=0.3)
        ax_o.legend(fontsize=7, loc="upper right")
        ax_o.set_title("orbit", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return save(fig, path)
