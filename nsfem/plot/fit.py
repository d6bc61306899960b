"""Plots of a fit: measured against fitted signals, and the misfit landscape of the global stage."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .common import dominant_period, figure, key_label, label_row, long_signal, save, zoom_panel, zoom_span


def fit_plot(path: str | Path, t: np.ndarray, measured: np.ndarray, fitted: np.ndarray, names: Sequence[str],
             misfit: float = float("nan")) -> Path:
    """One row per sensor: the measured signal (dots) and the fitted one (line), in um; a record too long to
    read at the plot's width is drawn as its envelopes with the last periods beside (see
    :func:`nsfem.plot.common.long_signal`)."""
    t = np.asarray(t, dtype=float)
    n = len(names)
    period = dominant_period(t, np.asarray(measured, dtype=float)[:, 0]) if t.size > 1 and n else None
    span = zoom_span(t, period)
    fig, axes = figure(nrows=n, sharex=True, figsize=(7.5 + 2.5 * bool(span), 2.2 * n + 0.6), squeeze=False)
    zooms = []
    for k, (ax, name) in enumerate(zip(axes[:, 0], names)):
        zoom = None
        if span:
            ax, zoom = zoom_panel(ax, width=0.28)
            zooms.append(zoom)
        long_signal(ax, t, 1e6 * measured[:, k], period=period, zoom=zoom, span=span, color="0.4",
                    label="measured", ls="none", marker=".", ms=2.5)
        long_signal(ax, t, 1e6 * fitted[:, k], period=period, zoom=zoom, span=span, color="tab:red",
                    label="fitted", lw=1.0)
        label_row(ax, zoom, f"{name} [µm]", k == n - 1)
        if k == 0:
            ax.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, frameon=False,
                      borderaxespad=0.2)
        else:
            ax.sharex(fig.axes[0])
    for zoom in zooms[1:]:
        zoom.set_title("")
    if t.size > 1:
        fig.axes[0].set_xlim(t[0], t[-1])
    fig.suptitle(f"measured and fitted signals (relative RMS misfit {100 * misfit:.3g} %)", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def landscape_plot(path: str | Path, keys: Sequence[str], samples: np.ndarray, misfit: np.ndarray,
                   estimate: np.ndarray) -> Path:
    """The global stage's misfit: against each key (one panel each), or over the plane of two keys
    (colour: log10 of the misfit); the estimate marked. Failed runs are left out."""
    ok = np.isfinite(misfit)
    x, f = samples[ok], misfit[ok]
    if len(keys) == 2:
        fig, ax = figure(figsize=(6.0, 5.0))
        sc = ax.scatter(x[:, 0], x[:, 1], c=np.log10(np.maximum(f, 1e-16)), cmap="viridis", s=30)
        fig.colorbar(sc, ax=ax, label="log10 of the relative misfit [-]")
        ax.plot(estimate[0], estimate[1], "r*", ms=12, label="estimate")
        ax.set_xlabel(key_label(keys[0]))
        ax.set_ylabel(key_label(keys[1]))
        ax.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), frameon=False, borderaxespad=0.2)
    else:
        fig, axes = figure(ncols=len(keys), figsize=(4.2 * len(keys), 3.8), squeeze=False)
        for k, (ax, key) in enumerate(zip(axes[0], keys)):
            ax.semilogy(x[:, k], np.maximum(f, 1e-16), "o", ms=4)
            ax.axvline(estimate[k], color="tab:red", ls=":", label="estimate")
            ax.set_xlabel(key_label(key))
            ax.set_ylabel("relative misfit [-]")
            ax.grid(True, which="both", alpha=0.3)
        axes[0, 0].legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), frameon=False,
                          borderaxespad=0.2)
    fig.suptitle(f"global stage: {int(ok.sum())} runs" + (f" ({int((~ok).sum())} failed)" if (~ok).any() else ""),
                 fontsize=10)
    fig.tight_layout()
    return save(fig, path)
