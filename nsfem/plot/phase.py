"""phase.png: phase portraits of the first modes at steady state, each read where its mode moves most.

A modal coordinate eta_j (of the open, non-rotating, mass-normalized modes, :func:`~nsfem.plot.data.modal_basis`)
is in sqrt(kg) m, which says nothing about the machine. Each portrait is drawn in the displacement and
velocity that mode j alone gives at its largest point: phi_j(x*) eta_j and phi_j(x*) eta_j', x* the node and
field (U axial, V or W lateral) where the mode shape phi_j is largest. One constant per mode, so the portrait
is the paper's fig. 3a (a closed orbit, flattened where the contact acts) in micrometres and mm/s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, _model_and_T, _window, hermite_refine, modal_basis, modal_coordinates

FIELD_NAMES = {"U": "axial U", "V": "bending V", "W": "bending W"}
#: the modes whose vibration the bar panel shows, and among which the portraits' modes are chosen
BAR_MODES = 12
#: the bar panel's log axis starts at this fraction of the largest bar (6 decades, the spectra's range)
BAR_DECADES_FLOOR = 1e-6
#: a portrait whose mean displacement exceeds this many times its span is drawn about its mean
OFFSET_RATIO = 3.0


def mode_peaks(system, count: int) -> list[dict] | None:
    """Per mode j < ``count`` of :func:`modal_basis`: where its shape is largest among the translations
    (U, and the nodal values of V and W, not their slopes): ``field``, ``x`` [m], ``segment``, ``scale``
    (phi_j there [1/sqrt(kg)], signed) and ``kind`` (the field with most of its kinetic energy). None
    without a finite-element model."""
    model, T = _model_and_T(system)
    if model is None:
        return None
    from ..analysis.modes import dominant_fields

    _, Phi = modal_basis(system)
    shapes = np.asarray(T @ Phi[:, :count])
    rows, where = [], []
    for name, space in model.spaces.items():
        xu = space.axial.doflocs[0][space.axial.nodal_dofs[0]] + space.x[0]
        rows.append(space.dofs["U"][space.axial.nodal_dofs[0]])
        where += [("U", float(x), name) for x in xu]
        for fld in "VW":
            rows.append(space.dofs[fld][space.bending.nodal_dofs[0]])
            where += [(fld, float(x), name) for x in space.x]
    rows = np.concatenate(rows)
    kinds = dominant_fields(model, shapes)
    out = []
    for j in range(shapes.shape[1]):
        k = int(np.argmax(np.abs(shapes[rows, j])))
        fld, x, seg = where[k]
        out.append({"field": fld, "x": x, "segment": seg, "scale": float(shapes[rows[k], j]), "kind": kinds[j]})
    return out


def phase_plot(result, system, path, modes: int = 3, steady_from: float | None = None) -> Path:
    """Phase portraits of ``modes`` modes for t >= ``steady_from`` (default: the last half of the run), each
    as the displacement [um] and velocity [mm/s] it gives where its shape is largest (:func:`mode_peaks`),
    and a bar per mode (the first :data:`BAR_MODES`) of that displacement's RMS about its mean; the modes
    drawn are the ``modes`` with the largest bars, in the order of their frequencies. Without a
    finite-element model (a system built from arrays) the portraits and bars are of the modal coordinates
    themselves."""
    if result.t.size < 2 or result.q.shape[0] == 0:
        raise NoPlotData("phase: the run has fewer than two samples or no coordinates")
    f, eta, deta = modal_coordinates(result, system)
    sel = _window(result.t, steady_from)
    t0 = float(result.t[sel][0])
    k = min(eta.shape[0], BAR_MODES)
    nm = max(1, min(int(modes), k))
    peaks = mode_peaks(system, k)
    dev = eta[:k, sel] - eta[:k, sel].mean(axis=1, keepdims=True)
    rms = np.sqrt(np.mean(dev ** 2, axis=1))
    if peaks is not None:
        rms = 1e6 * rms * np.abs([p["scale"] for p in peaks])
    # the modes that vibrate most (a rotor's axial modes barely move), in the order of their frequencies;
    # the first ones of the paper's fig. 3a where they carry the vibration
    drawn = sorted(np.argsort(-rms, kind="stable")[:nm].tolist())
    ncols = 2
    nrows = math.ceil((nm + 1) / ncols)
    fig, axes = figure(nrows=nrows, ncols=ncols, figsize=(FIGSIZE[0] * 1.15, FIGSIZE[1] * nrows / 2.0 + 0.4),
                       squeeze=False)
    axes = axes.ravel()
    kicks = [float(i["t"]) for i in result.impacts]
    for ax, j in zip(axes, drawn):
        x, dx = hermite_refine(result.t[sel], eta[j, sel], deta[j, sel], f[j], kicks)
        if peaks is not None:
            p = peaks[j]
            c = p["scale"]
            u = 1e6 * c * x
            # a static sag far larger than the vibration (a rotor under its weight) would label the axis with
            # five-digit numbers differing in the last: the portrait is drawn about the mean, which is named
            mean = float(np.mean(u))
            shift = mean if abs(mean) > OFFSET_RATIO * float(np.ptp(u)) else 0.0
            ax.plot(u - shift, 1e3 * c * dx, lw=0.7, color="tab:blue")
            ax.plot(1e6 * c * eta[j, sel][-1:] - shift, 1e3 * c * deta[j, sel][-1:], "o", ms=4, color="tab:red")
            ax.set_xlabel(f"{p['field']} of mode {j + 1}" + (f" about its mean {shift:.4g}" if shift else "")
                          + " [µm]")
            ax.set_ylabel(f"d{p['field']}/dt [mm/s]")
            ax.set_title(f"mode {j + 1}: {f[j]:.4g} Hz, {FIELD_NAMES[p['kind']]}\n"
                         f"at its largest, {p['field']} at x = {p['x']:.4g} m{_layer(p['segment'])}", fontsize=8)
        else:
            ax.plot(x, dx, lw=0.7, color="tab:blue")
            ax.plot(eta[j, sel][-1:], deta[j, sel][-1:], "o", ms=4, color="tab:red")
            ax.set_xlabel(rf"modal coordinate $\eta_{j + 1}$ [$\sqrt{{kg}}\,$m]")
            ax.set_ylabel(rf"$\dot\eta_{j + 1}$ [$\sqrt{{kg}}\,$m/s]")
            ax.set_title(f"mode {j + 1}: {f[j]:.4g} Hz", fontsize=8)
        ax.ticklabel_format(style="sci", scilimits=(-3, 4))
        ax.grid(True, alpha=0.3)
    from matplotlib.ticker import MaxNLocator

    ax = axes[nm]
    ax.set_ylabel("RMS [µm]" if peaks is not None else r"RMS of $\eta_j - \bar\eta_j$ [$\sqrt{kg}\,$m]")
    ax.bar(np.arange(1, k + 1), rms, color=["tab:blue" if i in drawn else "tab:gray" for i in range(k)])
    below = []
    if np.all(rms > 0):
        ax.set_yscale("log")
        floor = BAR_DECADES_FLOOR * float(rms.max())   # a mode 10^-13 below the rest would squash them into a line
        below = [i + 1 for i in range(k) if rms[i] < floor]
        ax.set_ylim(bottom=max(floor, 0.5 * float(rms.min())))
    ax.set_xlabel("mode number [-]")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("each mode's vibration" + (" at its largest point" if peaks is not None else "")
                 + " (blue: drawn)" + (f"\nbelow 1e-6 of the largest, not shown: mode {', '.join(map(str, below))}"
                                       if below else ""), fontsize=8)
    ax.grid(True, alpha=0.3, axis="y")
    for a in axes[nm + 1:]:
        a.set_visible(False)
    frame = result.info.get("frame", "rotating")
    fig.suptitle(f"Phase portraits of the modes that vibrate most, t = {t0:.3g} to {result.t[-1]:.3g} s "
                 f"(red: the end)\nmodes of the open, non-rotating structure; {frame} frame", fontsize=9)
    fig.tight_layout()
    return save(fig, path)


def _layer(segment: str) -> str:
    """' (upper layer)' for a delamination's sub-beam, else ''."""
    for layer in ("upper", "lower"):
        if segment.endswith(f"_{layer}"):
            return f" ({layer} layer)"
    return ""
