"""The figures of ``nsfem periodic``: orbit.png (the orbit over one period: the probes' orbits, the gaps and
contact forces) and floquet.png (the Floquet multipliers in the complex plane with the unit circle)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Sequence

import numpy as np

from .common import figure, save
from .sensors import finish_orbit_axes, orbit_pairs


def orbit_plot(path: str | Path, t: np.ndarray, signals: np.ndarray, sensors, gap: np.ndarray,
               normal_force: np.ndarray, labels: Sequence[str], rings: Sequence[tuple[float, float]] = (),
               title: str = "") -> Path:
    """One period of an orbit: a panel per orbit (a y-probe against a z-probe at one x, in µm, with the clearance
    circle of a ring at that x from ``rings`` [(x, clearance)]; the probes without a partner against time), and,
    with contacts, the gaps (``gap`` (m, K) [m], in µm) and normal forces (``normal_force`` (m, K) [N]) of the
    contacts that close or come nearest against the time after the section ``t[0]`` (in ms). Returns the path."""
    t = np.asarray(t, dtype=float)
    signals = np.asarray(signals, dtype=float).reshape(t.size, -1)
    gap, force = np.atleast_2d(gap), np.atleast_2d(normal_force)
    pairs = orbit_pairs(sensors)
    paired = {k for p in pairs for k in p}
    single = [k for k in range(len(sensors)) if k not in paired]
    top = len(pairs) + (1 if single else 0)
    m = gap.shape[0] if gap.size else 0
    ncols = max(top, 2 if m else 1, 1)
    fig = figure(figsize=(max(8.4, 4.0 * ncols), 4.2 + (3.2 if m else 0.0)), layout="constrained")[0]
    fig.axes[0].remove()
    grid = fig.add_gridspec(2 if m else 1, ncols)
    ms = 1e3 * (t - t[0])
    for c, (i, j) in enumerate(pairs):
        ax = fig.add_subplot(grid[0, c])
        _orbit(ax, signals[:, i], signals[:, j], sensors[i], sensors[j], rings)
    if single:
        ax = fig.add_subplot(grid[0, len(pairs)])
        for k in single:
            ax.plot(ms, 1e6 * signals[:, k], lw=1.0, label=sensors[k].name)
        ax.set_xlabel("time after the section [ms]")
        ax.set_ylabel("probe displacement [µm]")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
        ax.grid(True, alpha=0.3)
    if not top:
        ax = fig.add_subplot(grid[0, 0])
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no [[sensor]] in the scene: no probe orbit", ha="center", va="center")
    if m:
        shown = _contacts_shown(gap, force)
        ax_g, ax_f = fig.add_subplot(grid[1, : ncols // 2 or 1]), fig.add_subplot(grid[1, ncols // 2 or 1:])
        for k in shown:
            ax_g.plot(ms, 1e6 * gap[k], lw=1.0, label=labels[k])
            ax_f.plot(ms, force[k], lw=1.0, label=labels[k])
        ax_g.axhline(0.0, color="0.3", lw=0.8, ls="--")
        ax_g.set_xlabel("time after the section [ms]")
        ax_g.set_ylabel("gap [µm]")
        ax_f.set_xlabel("time after the section [ms]")
        ax_f.set_ylabel("normal contact force [N]")
        more = f" ({len(shown)} of {m} contacts: those nearest to closing)" if len(shown) < m else ""
        ax_g.set_title("gaps over the period" + more, fontsize=8)
        ax_f.set_title("normal forces over the period (impulses not drawn)", fontsize=8)
        for ax in (ax_g, ax_f):
            ax.grid(True, alpha=0.3)
        ax_f.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    if title:
        fig.suptitle(title, fontsize=9)
    return save(fig, path)


#: at most this many contacts' gaps and forces are drawn (those that close or come nearest)
MAX_CONTACTS = 6


def _contacts_shown(gap: np.ndarray, force: np.ndarray) -> list[int]:
    """The contacts drawn: those with a force first, then the smallest gaps, at most :data:`MAX_CONTACTS`."""
    order = np.lexsort((gap.min(axis=1), -force.max(axis=1)))
    return sorted(int(k) for k in order[:MAX_CONTACTS])


def _orbit(ax, y, z, sy, sz, rings) -> None:
    """One probe pair's orbit over the period, the ring's clearance circle at its x, equal scales."""
    y = 1e6 * (-1.0 if sy.direction[0] == "-" else 1.0) * np.asarray(y)
    z = 1e6 * (-1.0 if sz.direction[0] == "-" else 1.0) * np.asarray(z)
    ax.plot(y, z, lw=1.2, color="tab:blue")
    ax.plot(y[:1], z[:1], "o", ms=4, color="tab:red")
    finish_orbit_axes(ax, sy, rings, f"orbit at x = {sy.x:g} m ({sy.frame}), one period; dot: the section")


#: characters per line of floquet.png's title (8 pt on its 6 in width): the verdict runs to 150
TITLE_WIDTH = 85


def floquet_plot(path: str | Path, multipliers: np.ndarray, verdict: str, title: str = "", tol: float = 1e-6) -> Path:
    """The Floquet multipliers in the complex plane with the unit circle (stable: every one inside), each
    labelled with its modulus (the largest ones, up to eight labels); those beyond 1 + ``tol`` (the
    stability test's tolerance, :func:`nsfem.periodic.shooting.classify`) drawn as red crosses; the verdict
    in the title."""
    mu = np.asarray(multipliers, dtype=complex).ravel()
    fig, ax = figure(figsize=(6.0, 6.0), layout="constrained")
    a = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(np.cos(a), np.sin(a), color="0.3", lw=1.0, ls="--", zorder=1)
    outside = np.abs(mu) > 1.0 + tol
    ax.plot(mu.real[~outside], mu.imag[~outside], "o", ms=5, color="tab:blue", zorder=3)
    ax.plot(mu.real[outside], mu.imag[outside], "x", ms=8, mew=2, color="tab:red", zorder=3)
    order = np.argsort(-np.abs(mu))
    for k in order[:8]:
        if mu[k].imag < 0 and np.any(np.isclose(mu[order[:8]], np.conj(mu[k]))):
            continue   # a conjugate pair shares one label, on the upper one
        ax.annotate(f"{abs(mu[k]):.6g}", (mu[k].real, mu[k].imag), textcoords="offset points", xytext=(5, 5),
                    fontsize=7)
    reach = max(1.1, 1.1 * float(np.abs(mu).max(initial=0.0)))
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.axhline(0.0, color="0.8", lw=0.6, zorder=0)
    ax.axvline(0.0, color="0.8", lw=0.6, zorder=0)
    ax.set_xlabel("Re mu [-]")
    ax.set_ylabel("Im mu [-]")
    head = textwrap.fill(f"Floquet multipliers ({mu.size}; dashed: the unit circle): {verdict}", TITLE_WIDTH)
    ax.set_title(f"{textwrap.fill(title, TITLE_WIDTH)}\n{head}" if title else head, fontsize=8)
    ax.grid(True, alpha=0.3)
    return save(fig, path)


#: axis labels of the keys a branch is commonly continued over, by the key's last part ("quantity [unit]")
KEY_LABELS = {"speed_hz": "rotor speed [Hz]", "clearance": "clearance [m]", "friction": "friction coefficient [-]",
              "restitution": "restitution coefficient [-]", "stiffness": "stiffness [N/m]",
              "gravity": "gravity [m/s²]", "phase_deg": "phase [deg]", "magnitude": "unbalance [kg m]",
              "external": "external damping [1/s]", "damping": "damping [N s/m]"}


def key_label(key: str) -> str:
    """The axis label of a scene key: "<quantity> [<unit>]" for the keys of :data:`KEY_LABELS`, else the key
    with its unit read from a suffix (_hz, _s, _m, _deg) or "[scene unit]"."""
    last = key.rsplit(".", 1)[-1]
    if last in KEY_LABELS:
        return f"{key}: {KEY_LABELS[last]}" if last != "speed_hz" else KEY_LABELS[last]
    for suffix, unit in (("_hz", "Hz"), ("_s", "s"), ("_m", "m"), ("_deg", "deg")):
        if last.endswith(suffix):
            return f"{key} [{unit}]"
    return f"{key} [scene unit]"


def _runs(values: np.ndarray, stable: np.ndarray) -> list[tuple[int, int, bool]]:
    """(first, last, stable) index runs of equal stability; consecutive runs share their boundary point so the
    curve is drawn without a gap."""
    out, i = [], 0
    for j in range(1, values.size + 1):
        if j == values.size or stable[j] != stable[i]:
            out.append((i, min(j, values.size - 1), bool(stable[i])))
            i = j
    return out


def branch_plot(path: str | Path, key: str, points: Sequence[dict], sensors: Sequence[str],
                bifurcations: Sequence[dict] = (), doubled: Sequence[dict] = (), title: str = "") -> Path:
    """The resonance curves of a branch of periodic orbits: per sensor (a panel each) its amplitude (half the
    peak-to-peak over the period, in µm) against the key's value; stable parts solid, unstable dashed; the
    period-doubled branches in another colour; each bifurcation marked on the branch and labelled by its kind.
    ``points`` (and each doubled branch's "points") are dicts with "value", "stable", "amplitudes" {sensor: m}.
    Without sensors the largest |coordinate| over the period ("orbit_q_max"; else "section_q_max", the section
    state's, which jumps where the section moves) is drawn instead (it has no unit of length: said in the label).
    Returns the path."""
    names = list(sensors) or [None]
    fig, axes = figure(nrows=len(names), ncols=1, figsize=(8.4, 1.0 + 3.0 * len(names)), layout="constrained",
                       squeeze=False, sharex=True)
    marks = {"fold": "s", "period-doubling": "D", "neimark-sacker": "^"}

    def curve(pts, name):
        x = np.array([p["value"] for p in pts], dtype=float)
        y = np.array([1e6 * p["amplitudes"][name] if name else p.get("orbit_q_max", p.get("section_q_max", 0.0))
                      for p in pts], float)
        return x, y, np.array([bool(p["stable"]) for p in pts])

    for ax, name in zip(axes[:, 0], names):
        for pts, color, what in [(points, "tab:blue", f"period {points[0].get('multiple', 1) if points else 1}")] + [
                (d["points"], "tab:orange", f"period {d['multiple']} (doubled)") for d in doubled if d["points"]]:
            if not pts:
                continue
            x, y, st = curve(pts, name)
            for i, j, s in _runs(x, st):
                ax.plot(x[i:j + 1], y[i:j + 1], color=color, lw=1.5, ls="-" if s else "--",
                        label=f"{what}, {'stable' if s else 'unstable'}")
            ax.plot(x, y, ".", ms=3, color=color)
        x, y, st = curve(points, name) if points else (np.zeros(0), np.zeros(0), np.zeros(0, bool))
        for b in bifurcations:
            yb = _at(x, y, st, float(b["value"]))
            if yb is None:
                continue
            ax.plot([b["value"]], [yb], marks.get(b["kind"], "o"), ms=7, color="tab:red", zorder=4)
            ax.annotate(f"{b['kind']} {b['value']:.6g}", (b["value"], yb), textcoords="offset points", xytext=(6, 6),
                        fontsize=7, color="tab:red")
        ax.set_ylabel(f"{name}: amplitude [µm]" if name else "largest coordinate over the period [model unit]")
        ax.grid(True, alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        seen = dict(zip(labels, handles))
        if seen:
            ax.legend(seen.values(), seen.keys(), fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    axes[-1, 0].set_xlabel(key_label(key))
    head = "periodic orbits: solid stable, dashed unstable; red marks: bifurcations"
    axes[0, 0].set_title(f"{title}\n{head}" if title else head, fontsize=8)
    return save(fig, path)


def _at(x: np.ndarray, y: np.ndarray, stable: np.ndarray, value: float) -> float | None:
    """The curve's y at ``value`` between two consecutive points that bracket it (those whose stability differs
    first), linearly; None where no pair brackets it."""
    pairs = [i for i in range(x.size - 1) if min(x[i], x[i + 1]) <= value <= max(x[i], x[i + 1])]
    if not pairs:
        return None
    i = next((i for i in pairs if stable[i] != stable[i + 1]), pairs[0])
    s = 0.0 if x[i + 1] == x[i] else (value - x[i]) / (x[i + 1] - x[i])
    return float(y[i] + s * (y[i + 1] - y[i]))
