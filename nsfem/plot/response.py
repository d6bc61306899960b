"""Bode and polar plots of a steady unbalance response (``nsfem response --png``): one PNG, the Bode plot
(amplitude and phase lag against speed, the peaks' half-power bands shaded) on the left, the polar plot
(the 1x vector per speed, lag clockwise from the reference mark) on the right."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save


def plot_response(path: str | Path, report: dict, title: str = "", run_speed_hz: float = 0.0) -> Path:
    """Write the Bode and polar plots of ``report`` (:func:`nsfem.analysis.response.response_report`)."""
    fig, first = figure(figsize=(11.0, 6.0), layout="constrained")
    first.remove()
    grid = fig.add_gridspec(2, 2, width_ratios=(1.6, 1.0))
    amp_ax = fig.add_subplot(grid[0, 0])
    ph_ax = fig.add_subplot(grid[1, 0], sharex=amp_ax)
    polar = fig.add_subplot(grid[:, 1], projection="polar")
    polar.set_theta_zero_location("N")
    polar.set_theta_direction(-1)                         # lag clockwise, as probes' polar plots read
    s = np.asarray(report["speeds_hz"])
    for j, (name, v) in enumerate(report["sensors"].items()):
        a, p = 1e6 * np.asarray(v["amplitude_m"]), np.asarray(v["phase_deg"])
        line, = amp_ax.plot(s, a, "-", label=name)
        ph_ax.plot(s, p, ".", ms=2, color=line.get_color())
        bad = np.asarray(report.get("unstable", [False] * s.size), dtype=bool)
        polar.plot(np.radians(p), np.where(bad, np.nan, a), "-", color=line.get_color())
        if bad.any():                                     # unstable speeds: dotted (no steady state)
            polar.plot(np.radians(p), np.where(bad | np.r_[bad[1:], False] | np.r_[False, bad[:-1]], a, np.nan),
                       ":", lw=1, color=line.get_color())
        polar.plot(np.radians(p[:1]), a[:1], "o", ms=4, color=line.get_color())   # the lowest speed
    for pk in report["peaks"]:
        amp_ax.axvspan(*pk["band_hz"], color="0.85", zorder=0)
        amp_ax.annotate(f"{pk['speed_hz']:.4g} Hz\nAF {pk['amplification_factor']:.3g}",
                        (pk["speed_hz"], 1e6 * pk["amplitude_m"]), fontsize=7, ha="center", va="bottom")
    for j, (a, b) in enumerate(report.get("unstable_ranges_hz", [])):  # no steady state there
        for ax in (amp_ax, ph_ax):
            ax.axvspan(a, s[-1] if b is None else b, color="tab:red", alpha=0.12, zorder=0,
                       label="structure unstable: no steady state" if ax is amp_ax and j == 0 else None)
    if run_speed_hz > 0 and s[0] <= run_speed_hz <= s[-1]:
        for ax in (amp_ax, ph_ax):
            ax.axvline(run_speed_hz, color="k", ls=":", lw=1)
    amp_ax.set_ylabel("1x amplitude [um]")
    amp_ax.legend(fontsize=8)
    ph_ax.set_ylabel("phase lag [deg]")
    ph_ax.set_ylim(0, 360)
    ph_ax.set_yticks(range(0, 361, 90))
    ph_ax.set_xlabel("speed [Hz]")
    polar.set_title("polar (um; lag clockwise; dot: lowest speed" + ("; dotted: unstable speeds)" if any(
        report.get("unstable", [])) else ")"), fontsize=9)
    for ax in (amp_ax, ph_ax):
        ax.grid(alpha=0.3)
    fig.suptitle(title or "unbalance response", fontsize=10)
    return save(fig, path)
