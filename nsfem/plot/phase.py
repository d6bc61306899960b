"""phase.png: phase portraits of the first modes at steady state."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, _model_and_T, _window, hermite_refine, modal_basis, modal_coordinates


def phase_plot(result, system, path, modes: int = 3, steady_from: float | None = None) -> Path:
    """Phase portraits eta_j' over eta_j of the first ``modes`` modal coordinates (see
    :func:`modal_basis`) for t >= ``steady_from`` (default: the last half of the run), and
    the RMS of every modal coordinate in that window."""
    if result.t.size < 2 or result.q.shape[0] == 0:
        raise NoPlotData("phase: the run has fewer than two samples or no coordinates")
    f, eta, deta = modal_coordinates(result, system)
    sel = _window(result.t, steady_from)
    t0 = float(result.t[sel][0])
    nm = max(1, min(int(modes), eta.shape[0]))
    fields = _mode_fields(system, nm)
    ncols = 2 if nm + 1 > 1 else 1
    nrows = math.ceil((nm + 1) / ncols)
    fig, axes = figure(nrows=nrows, ncols=ncols, figsize=(FIGSIZE[0], FIGSIZE[1] * nrows / 2.0), squeeze=False)
    axes = axes.ravel()
    kicks = [float(i["t"]) for i in result.impacts]
    for j in range(nm):
        ax = axes[j]
        x, dx = hermite_refine(result.t[sel], eta[j, sel], deta[j, sel], f[j], kicks)
        ax.plot(x, dx, lw=0.7, color="tab:blue")
        ax.plot(eta[j, sel][-1:], deta[j, sel][-1:], "o", ms=4, color="tab:red", label="end")
        ax.set_xlabel(rf"$\eta_{j + 1}$ [$\sqrt{{kg}}\,$m]")
        ax.set_ylabel(rf"$\dot\eta_{j + 1}$ [$\sqrt{{kg}}\,$m/s]")
        ax.set_title(f"mode {j + 1}: {f[j]:.4g} Hz{fields[j]}", fontsize=9)
        ax.ticklabel_format(style="sci", scilimits=(-2, 3))
        ax.grid(True, alpha=0.3)
    ax = axes[nm]
    k = min(eta.shape[0], 12)
    rms = np.sqrt(np.mean((eta[:k, sel] - eta[:k, sel].mean(axis=1, keepdims=True)) ** 2, axis=1))
    ax.bar(np.arange(1, k + 1), rms, color=["tab:blue" if i < nm else "tab:gray" for i in range(k)])
    ax.set_yscale("log" if np.all(rms > 0) else "linear")
    ax.set_xlabel("mode")
    ax.set_ylabel(r"RMS of $\eta_j - \bar\eta_j$ [$\sqrt{kg}\,$m]")
    ax.set_title("vibration per mode (plotted in blue)", fontsize=9)
    ax.grid(True, alpha=0.3, axis="y")
    for a in axes[nm + 1:]:
        a.set_visible(False)
    fig.suptitle(f"Modal phase portraits, t = {t0:.3g} to {result.t[-1]:.3g} s "
                 f"(open, non-rotating mass-normalized modes)", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def _mode_fields(system, count: int) -> list[str]:
    """', bending W' etc. per mode when the model is known, else empty strings."""
    model, T = _model_and_T(system)
    if model is None:
        return [""] * count
    from ..analysis.modes import dominant_fields

    _, Phi = modal_basis(system)
    names = {"U": "axial U", "V": "bending V", "W": "bending W"}
    return [f", {names[c]}" for c in dominant_fields(model, np.asarray(T @ Phi[:, :count]))]
