"""Campbell diagram: the damped branches against rotor speed (rotating frame, or inertial-frame whirl), the 1x
line, the critical speeds where it crosses the branches (or the gravity resonances), the run speed, the bands.

Each branch is drawn twice: a broad band coloured by its logarithmic decrement at each speed (the colour bar "log
dec": a sequential map from 0, undamped, to the 95th percentile of the decrements drawn; a growing mode, log dec < 0, in
:data:`UNSTABLE_COLOUR` whatever its value), and over it a thin dark line in the style of its whirl (inertial
frame) or contact state (rotating frame). Each damped critical speed is listed in the legend with its log dec."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from .common import figure, save

#: whirl code -> (legend name, line style) of a branch's line (nsfem.analysis.whirl codes; its colour is its log dec)
WHIRL_STYLE = {1: ("forward whirl", "-"), -1: ("backward whirl", "--"), 0: ("planar (no whirl)", "-."),
               2: ("axial", (0, (3, 1, 1, 1, 1, 1)))}   # (dash-dot-dot: the 1x line is the dotted one)
#: colour map of the log decrements >= 0, and the colour of a growing mode (log dec < 0)
LOG_DEC_MAP = "viridis_r"
UNSTABLE_COLOUR = "red"
#: the colour scale ends at this quantile of the log decs drawn (a few points near a branch's birth from two
#: overdamped roots reach hundreds and would wash out the rest)
TOP_QUANTILE = 0.95
#: width [points] of the coloured band under each branch
BAND_WIDTH = 4.5
#: at most this many critical speeds are listed one by one in the legend (then one entry for all)
LISTED_CRITICAL = 8
#: characters per title line at the figure's width and font size
TITLE_WIDTH = 88
#: at most this many title lines (then the plot's own line, what is drawn)
TITLE_LINES = 3


def campbell_plot(path: str | Path, open_res, closed_res=None, critical=(), undamped=(), resonances=None,
                  bands=(), title: str = "", run_speed_hz: float | None = None) -> Path:
    """Write the diagram of :func:`nsfem.analysis.campbell.campbell` results.

    Inertial frame (``open_res.whirl`` given): the open branches, each drawn in the style of its whirl label;
    ``critical``: the damped critical speeds (:class:`nsfem.analysis.branches.Crossing`, ``branch``
    indexing :func:`~nsfem.analysis.campbell.shown_branches`), drawn on their branches; ``undamped``: the
    undamped critical speeds, drawn apart as a reference. Rotating frame: open and closed branches,
    ``resonances`` maps "open"/"closed" to gravity-resonance speeds (undamped). ``bands``: (low, high)
    speed intervals shaded (divergence or instability)."""
    from ..analysis.campbell import crossing_log_decrement, shown_branches
    from ..analysis.whirl import WHIRL_NAMES

    inertial = open_res.whirl is not None
    s = np.asarray(open_res.speeds_hz, dtype=float)
    top = float(s.max()) if s.size else 1.0
    fig, ax = figure(figsize=(7.6, 6.4), layout="constrained")
    # a band of zero width (an isotropic shaft's double divergence speed) is no band
    shaded = [(lo, min(hi, top)) for lo, hi in bands if lo < top and hi - lo > 1e-9 * max(abs(lo), 1.0)]
    for lo, hi in shaded:
        ax.axvspan(lo, hi, color="tab:red", alpha=0.08, lw=0)
    if shaded:
        ax.plot([], [], color="tab:red", alpha=0.3, lw=6, label="unstable" if inertial else "divergence band")
    fmax = 0.0
    sets = [(open_res, "open")]
    if closed_res is not None and closed_res is not open_res and not inertial:
        sets.append((closed_res, "closed"))
    labelled = set()
    drawn = []  # (x, y, log dec) of each branch, coloured once the range of the log decs is known
    for res, name in sets:
        B = res.branches
        for j, b in enumerate(shown_branches(res)):
            here = [c for c in critical if c.branch == j] if name == "open" else []
            x, y, d = _with_crossings(B.speeds_hz, B.frequencies_hz[b], [c.speed_hz for c in here],
                                      branch_log_decrements(B.eigenvalues[b], res.resolution_per_s),
                                      [crossing_log_decrement(c, res.resolution_per_s) for c in here])
            if not np.any(np.isfinite(y)):
                continue
            fmax = max(fmax, float(np.nanmax(y)))
            text, style = WHIRL_STYLE[int(B.label[b])] if inertial else (f"contacts {name}",
                                                                          "-" if name == "open" else "--")
            ax.plot(x, y, linestyle=style, color="k", lw=0.9, label=None if text in labelled else text, zorder=3)
            labelled.add(text)
            drawn.append((x, y, d))
    _log_dec_bands(fig, ax, drawn)
    ax.plot([0.0, top], [0.0, top], ":", color="k", lw=1,
            label="1x (unbalance forcing)" if inertial else "1x (gravity forcing, rotating frame)")
    listed = [c for c in critical if c.speed_hz <= top]
    crit = np.array([c.speed_hz for c in listed], dtype=float)
    entries = []  # the critical speeds' log decs: legend entries without a mark, in a column of their own
    if crit.size:
        ax.plot(crit, crit, "o", color="k", ms=6, label="critical speeds (1x crossings of damped branches)", zorder=4)
        dec = [crossing_log_decrement(c, open_res.resolution_per_s) for c in listed]
        if len(listed) <= LISTED_CRITICAL:
            entries = [f"{c.speed_hz:.2f} Hz ({WHIRL_NAMES[int(c.whirl)]}): log dec {d:.3g}"
                       + (" (unstable)" if d < 0 else "") for c, d in zip(listed, dec)]
        else:
            entries = [f"{len(listed)} critical speeds: log dec {min(dec):.3g} to {max(dec):.3g}"]
        entries.insert(0, "critical speeds' log decrements:")
    und = np.asarray(undamped, dtype=float)
    und = und[und <= top]
    if und.size:
        ax.plot(und, und, "D", color="tab:purple", mfc="none", ms=7, mew=1.0,
                label="undamped critical speeds (reference)")
    for name, marker, color in (("open", "o", "tab:blue"), ("closed", "s", "tab:orange")):
        r = np.asarray((resonances or {}).get(name, []), dtype=float)
        r = r[r <= top]
        if r.size:
            ax.plot(r, r, marker, color=color, mfc="none", ms=9,
                    label=f"gravity resonances, contacts {name} (undamped 1x crossings)")
    if run_speed_hz:
        ax.axvline(run_speed_hz, color="tab:brown", lw=1.0, ls="-.", label=f"run speed {run_speed_hz:g} Hz")
    ax.set_xlabel("rotor speed [Hz]")
    ax.set_ylabel("frequency [Hz]")
    if s.size and top > s.min():  # (one speed: matplotlib's default span around it)
        ax.set_xlim(s.min(), top)
    ax.set_ylim(0.0, 1.05 * max(fmax, top))
    ax.grid(True, alpha=0.3)
    what = ("damped natural frequencies (inertial frame: whirl frequencies)" if inertial
            else "damped natural frequencies (rotating frame)")
    if inertial and closed_res is not None and closed_res is not open_res:
        what += ", contacts open"  # (the closed ones are in the JSON)
    ax.set_title("\n".join(_wrap(title) + [what]), fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if entries:
        from matplotlib.lines import Line2D

        blank = Line2D([], [], linestyle="none")
        rows = max(len(labels), len(entries))   # the legend fills columns first: general entries, then these
        handles = handles + [blank] * (rows - len(labels)) + [blank] * rows
        labels = labels + [""] * (rows - len(labels)) + entries + [""] * (rows - len(entries))
    fig.legend(handles, labels, loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    return save(fig, path)


def report_plot(path: str | Path, rep: dict, title: str = "", run_speed_hz: float | None = None) -> Path:
    """:func:`campbell_plot` of a :func:`nsfem.analysis.campbell.campbell_report` (its "_results", "_bands"
    and "_critical" entries still in it)."""
    res = rep["_results"]
    inertial = rep["frame"] == "inertial"
    return campbell_plot(path, res["open"], res["closed"], rep["_critical"]["open"],
                         rep.get("undamped_critical_speeds_hz", {}).get("open", []),
                         None if inertial else rep["gravity_resonances_hz"], rep["_bands"], title, run_speed_hz)


def scene_campbell(path: str | Path, scene, model, reduction=None, count: int = 6, warn=None) -> Path:
    """The Campbell diagram ``nsfem run`` draws when ``output.plots`` lists campbell: the default speeds of
    :func:`nsfem.analysis.campbell.campbell_report` (0 to past the first critical or divergence speeds, at
    least twice the run speed), ``count`` branches, the run speed marked; the report's warnings go to
    ``warn(text)``."""
    from ..analysis.campbell import campbell_report

    rep = campbell_report(scene, model, None, count, reduction)
    for text in rep["warnings"]:
        if warn is not None:
            warn(f"campbell: {text}")
    return report_plot(path, rep, scene.title, scene.rotation.speed_hz)


def _wrap(title: str) -> list[str]:
    """``title`` in as few lines of at most :data:`TITLE_WIDTH` characters as it needs, of even lengths
    (no single word left on a line of its own), at most :data:`TITLE_LINES` of them."""
    if not title:
        return []
    lines = math.ceil(len(title) / TITLE_WIDTH)
    out = textwrap.wrap(title, TITLE_WIDTH)
    for width in range(math.ceil(len(title) / lines), TITLE_WIDTH + 1):
        even = textwrap.wrap(title, width)
        if len(even) <= lines:
            out = even
            break
    if len(out) > TITLE_LINES:  # a title longer than the figure can hold: its start, marked as cut
        out = out[:TITLE_LINES]
        out[-1] = out[-1][: TITLE_WIDTH - 3] + "..."
    return out


def _with_crossings(s: np.ndarray, f: np.ndarray, speeds, d: np.ndarray | None = None, d_at=()):
    """The branch's points (s, f) with the crossings (x, x) inserted in speed order, so that each marker
    lies on the line drawn; with ``d`` (per point) and ``d_at`` (per crossing), also the third coordinate
    (the log decrement) in the same order: (x, y, d)."""
    d = np.full(np.shape(f), np.nan) if d is None else np.asarray(d, dtype=float)
    if not len(speeds):
        return s, f, d
    x = np.concatenate([s, np.asarray(speeds, dtype=float)])
    y = np.concatenate([f, np.asarray(speeds, dtype=float)])
    z = np.concatenate([d, np.asarray(d_at, dtype=float) if len(d_at) else np.full(len(speeds), np.nan)])
    order = np.argsort(x, kind="stable")
    return x[order], y[order], z[order]


def branch_log_decrements(eigenvalues: np.ndarray, resolution: float = 0.0) -> np.ndarray:
    """-2 pi Re(lambda) / Im(lambda) of a branch's roots (nan where it does not exist; 0 for a real part within
    ``resolution``, round-off: an undamped mode is not drawn as unstable)."""
    lam = np.asarray(eigenvalues, dtype=complex)
    re = np.where(np.abs(lam.real) <= resolution, 0.0, lam.real)
    with np.errstate(invalid="ignore", divide="ignore"):
        return -2 * math.pi * re / lam.imag + 0.0


def log_dec_norm(decrements):
    """(colour map, norm) of the bands: ``LOG_DEC_MAP`` from 0 to the :data:`TOP_QUANTILE` quantile of the finite
    log decs (at least 1e-3, so that an undamped diagram has a scale; above it the map's last colour: a branch born
    from two overdamped roots starts at a log dec of hundreds), anything below 0 in :data:`UNSTABLE_COLOUR`."""
    import matplotlib
    from matplotlib.colors import Normalize

    d = np.asarray(decrements, dtype=float)
    d = d[np.isfinite(d)]
    top = max(float(np.quantile(d, TOP_QUANTILE)) if d.size else 0.0, 1e-3)
    cmap = matplotlib.colormaps[LOG_DEC_MAP].with_extremes(under=UNSTABLE_COLOUR)
    return cmap, Normalize(vmin=0.0, vmax=top)


def _log_dec_bands(fig, ax, drawn) -> None:
    """The branches' coloured bands (a segment between two points takes the mean of their log decs; a segment
    with a growing end is unstable) and the colour bar."""
    from matplotlib.collections import LineCollection

    every = np.concatenate([d for _, _, d in drawn]) if drawn else np.zeros(0)
    cmap, norm = log_dec_norm(every)
    for x, y, d in drawn:
        seg = np.stack([np.column_stack([x[:-1], y[:-1]]), np.column_stack([x[1:], y[1:]])], axis=1)
        ok = np.isfinite(seg).all(axis=(1, 2)) & np.isfinite(d[:-1]) & np.isfinite(d[1:])
        value = np.where((d[:-1] < 0) | (d[1:] < 0), np.minimum(d[:-1], d[1:]), 0.5 * (d[:-1] + d[1:]))
        if np.any(ok):
            ax.add_collection(LineCollection(seg[ok], array=value[ok], cmap=cmap, norm=norm, linewidths=BAND_WIDTH,
                                             capstyle="round", zorder=2), autolim=False)
    from matplotlib.cm import ScalarMappable

    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, extend="both", pad=0.02, fraction=0.05)
    undamped = not np.any(np.abs(every[np.isfinite(every)]) > 0)
    bar.set_label(f"log dec [-] (below 0, {UNSTABLE_COLOUR}: unstable)" + ("; every branch 0: undamped" if undamped
                                                                            else ""))
