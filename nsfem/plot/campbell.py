"""Campbell diagram: the damped branches against rotor speed (rotating frame, or inertial-frame whirl), the 1x
line, the critical speeds where it crosses the branches (or the gravity resonances), the run speed, the bands."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from .common import figure, save

#: whirl code -> (legend name, colour, line style) of a branch (nsfem.analysis.whirl codes)
WHIRL_STYLE = {1: ("forward whirl", "tab:blue", "-"), -1: ("backward whirl", "tab:orange", "--"),
               0: ("planar (no whirl)", "tab:gray", "-."), 2: ("axial", "tab:green", ":")}
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
    from ..analysis.campbell import shown_branches

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
    for res, name in sets:
        B = res.branches
        for j, b in enumerate(shown_branches(res)):
            x, y = _with_crossings(B.speeds_hz, B.frequencies_hz[b], [c.speed_hz for c in critical if c.branch == j]
                                   if name == "open" else [])
            if not np.any(np.isfinite(y)):
                continue
            fmax = max(fmax, float(np.nanmax(y)))
            if inertial:
                text, color, style = WHIRL_STYLE[int(B.label[b])]
            else:
                text, color, style = (f"contacts {name}", "tab:blue" if name == "open" else "tab:orange",
                                      "-" if name == "open" else "--")
            ax.plot(x, y, style, color=color, lw=1.3, label=None if text in labelled else text)
            labelled.add(text)
    ax.plot([0.0, top], [0.0, top], ":", color="k", lw=1,
            label="1x (unbalance forcing)" if inertial else "1x (gravity forcing, rotating frame)")
    crit = np.array([c.speed_hz for c in critical], dtype=float)
    crit = crit[crit <= top]
    if crit.size:
        ax.plot(crit, crit, "o", color="k", ms=6, label="critical speeds (1x crossings of damped branches)")
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
        ax.axvline(run_speed_hz, color="tab:red", lw=1.0, ls="-.", label=f"run speed {run_speed_hz:g} Hz")
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
    fig.legend(loc="outside lower center", ncol=2, fontsize=8, frameon=False)
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


def _with_crossings(s: np.ndarray, f: np.ndarray, speeds) -> tuple[np.ndarray, np.ndarray]:
    """The branch's points (s, f) with the crossings (x, x) inserted in speed order, so that each marker
    lies on the line drawn."""
    if not len(speeds):
        return s, f
    x = np.concatenate([s, np.asarray(speeds, dtype=float)])
    y = np.concatenate([f, np.asarray(speeds, dtype=float)])
    order = np.argsort(x, kind="stable")
    return x[order], y[order]
