"""Plots of a transient run (``output.plots``): phase, gap, psd and forces (paper fig. 3).

Each function takes a :class:`~nsfem.result.Result`, the
:class:`~nsfem.integrate.ContactSystem` it was computed on (``run_scene`` returns both) and
a path, writes one PNG atomically (temporary file in the same directory, then a rename,
see :func:`nsfem.plot.common.save`) and returns the path:

- :func:`phase_plot`: phase portraits of the first modal coordinates at steady state,
- :func:`gap_plot`: the gap at the middle of each delamination, and each crack's opening, over time,
- :func:`psd_plot`: Welch PSD of the transverse displacement in an undamaged region,
- :func:`forces_plot`: contact forces over time and the impact impulses (a crack's faces as one),
- :func:`write_plots`: the plots named in ``output.plots`` (``campbell`` is drawn by
  :func:`nsfem.plot.campbell_plot`), skipping those without data.

A plot that has nothing to show (no contacts, no contact ever loaded, no model to locate a
point on) raises :class:`NoPlotData`; :func:`write_plots` turns that into a warning.

>>> from nsfem import load_scene
>>> from nsfem.simulate import run_scene
>>> result, system = run_scene(load_scene(None, ["mesh.elements=20", "simulation.t_end=0.02"]))
>>> [m["x"] for m in delamination_middles(system)]
[0.5]
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from ..errors import NsfemError
from .common import figure, save

#: plots this module draws, in the order of ``output.plots``
RESULT_PLOTS = ("phase", "gap", "psd", "forces")
FIGSIZE = (6.4, 4.8)


class NoPlotData(NsfemError):
    """The run holds nothing this plot could show; the message says why."""


# --------------------------------------------------------------------------- helpers
def _dense(A) -> np.ndarray:
    return np.asarray(A.toarray() if hasattr(A, "toarray") else A, dtype=float)


def _model_and_T(system):
    """(model, T with q_full = T q) from ``system.info``, or (None, None)."""
    info = getattr(system, "info", None) or {}
    model, red = info.get("model"), info.get("reduction")
    if model is None:
        return None, None
    return model, (red.T if red is not None else model.T)


def _speed_hz(result, system) -> float:
    s = result.info.get("speed_hz")
    if s is None:
        s = getattr(system, "omega", 0.0) / (2.0 * math.pi)
    return float(s or 0.0)


def _window(t: np.ndarray, steady_from: float | None) -> np.ndarray:
    """Boolean mask of the samples at t >= steady_from (default: the last half of the run)."""
    if t.size == 0:
        return np.zeros(0, bool)
    if steady_from is None:
        steady_from = t[0] + 0.5 * (t[-1] - t[0])
    return t >= steady_from


def modal_basis(system) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies [Hz], Phi): the mass-normalized modes of the open, non-rotating system.

    Eigenvectors of K0 phi = w^2 M phi in the system's (reduced) coordinates, ascending,
    Phi^T M Phi = I, so q = Phi eta and eta = Phi^T M q. K0 is the non-rotating elastic
    stiffness T^T K_full T (the paper's "eigenshapes of the non-rotating model") when the
    system carries its finite-element model; otherwise the symmetric part of ``system.Q``
    (which at a nonzero speed also holds the centrifugal terms).
    """
    import scipy.linalg as sla

    M = np.asarray(system.M, dtype=float)
    model, T = _model_and_T(system)
    if model is not None:
        K = _dense(T.T @ (model.K_full @ T))
    else:
        Q = np.asarray(system.Q, dtype=float)
        K = 0.5 * (Q + Q.T)
    K = 0.5 * (K + K.T)
    lam, Phi = sla.eigh(K, M)
    return np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * math.pi), Phi


def modal_coordinates(result, system) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies [Hz], eta, eta') of every mode of :func:`modal_basis`: eta = Phi^T M q."""
    f, Phi = modal_basis(system)
    P = Phi.T @ np.asarray(system.M, dtype=float)
    return f, P @ result.q, P @ result.v


def welch_psd(signal, dt: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(f [Hz], one-sided PSD [unit^2/Hz]) of a uniformly sampled signal (Hann, 50 % overlap,
    mean removed); default segments of half the record (three averages)."""
    from scipy.signal import welch

    x = np.asarray(signal, dtype=float)
    n = x.size
    if nperseg is None:
        nperseg = n if n < 32 else max(32, n // 2)
    return welch(x, fs=1.0 / dt, nperseg=min(nperseg, n), detrend="constant", scaling="density")


def _uniform(t: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """(dt, y on a uniform grid): output times are uniform except for round-off; else interpolate."""
    d = np.diff(t)
    dt = float(np.median(d))
    if np.allclose(d, dt, rtol=1e-6, atol=0.0):
        return dt, y
    grid = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    return dt, np.interp(grid, t, y)


def delamination_middles(system) -> list[dict]:
    """Per delamination (contacts on one interface), stator ring, crack or stop: its contacts and
    the one nearest its midspan.

    Each entry: ``name`` ("delamination.0", "crack.0", "obstacle.1", ...), ``kind`` ("interface",
    "stator", "crack" or "stop"), ``indices`` (contact rows), ``middle`` (the row nearest the
    middle), ``x`` (its position [m]) and ``span`` (start, end) [m]. Interfaces are grouped by the
    pair of sub-beams they join and their span is the sub-beams' length; a crack's two front ends
    are one group; without a model, contacts are grouped by label prefix and the span is that of
    their positions.
    """
    cs = system.model_contacts
    m = cs.m
    if m == 0:
        return []
    labels = list(cs.labels)
    xs = np.asarray(cs.x, dtype=float)
    model, _ = _model_and_T(system)
    groups: dict = {}
    if model is not None and len(model.stack.contacts) == m:
        for k, c in enumerate(model.stack.contacts):
            if c.kind == "interface":
                seg = model.stack.segment(c.segments[0])
                key = ("interface", tuple(c.segments))
                span = (seg.start, seg.end)
                name = labels[k].rsplit(".", 1)[0] if labels[k].startswith("delamination.") \
                    else f"interface {c.segments[0]}/{c.segments[1]}"
            elif c.angle is not None:   # a stator's facets: one ring, one panel
                name = labels[k].rsplit(".", 1)[0]
                key, span = ("stator", name), (c.x, c.x)
            elif c.kind == "crack":     # a crack's front ends: one crack, one panel
                name = c.table_key
                key, span = ("crack", tuple(c.segments), c.x), (c.x, c.x)
            else:
                key, span, name = ("stop", k), (c.x, c.x), labels[k]
            groups.setdefault(key, {"name": name, "kind": key[0], "indices": [], "span": span})["indices"].append(k)
    else:
        for k, lab in enumerate(labels):
            head = lab.split(".", 1)[0]
            key = lab.rsplit(".", 1)[0] if head in ("delamination", "stator", "crack") and lab.count(".") == 2 else lab
            kind = {"delamination": "interface", "stator": "stator", "crack": "crack"}.get(head, "stop")
            groups.setdefault(key, {"name": key, "kind": kind, "indices": []})["indices"].append(k)
        for g in groups.values():
            gx = xs[g["indices"]]
            g["span"] = (float(np.nanmin(gx)), float(np.nanmax(gx))) if np.isfinite(gx).any() else (np.nan, np.nan)
    out = []
    for g in groups.values():
        idx = np.asarray(g["indices"])
        mid = 0.5 * (g["span"][0] + g["span"][1])
        if np.isfinite(mid) and np.isfinite(xs[idx]).all():
            k = int(idx[np.argmin(np.abs(xs[idx] - mid))])
        else:
            k = int(idx[len(idx) // 2])
        out.append({"name": g["name"], "kind": g["kind"], "indices": [int(i) for i in idx], "middle": k,
                    "x": float(xs[k]), "span": tuple(float(s) for s in g["span"])})
    return out


def closed_intervals(result, k, every: bool = True) -> list[tuple[float, float]]:
    """[(t_close, t_release)] of contact row k: from the events when the integrator records
    them (exact), else from the sampled states. ``k`` may be a list of rows (a crack's front
    ends): closed when all of them are (``every``; else when any is: the crack at least partly
    closed)."""
    t = result.t
    if t.size == 0:
        return []
    rows = [int(r) for r in np.atleast_1d(k)]
    events = [e for e in result.events if isinstance(e.get("after"), dict) and "closed" in e["after"]]
    spans = []
    if events:
        together = all if every else any
        closed, start = together(result.state[r, 0] != 0 for r in rows), float(t[0])
        for e in sorted(events, key=lambda e: e["t"]):
            now = together(r in e["after"]["closed"] for r in rows)
            if now and not closed:
                start = float(e["t"])
            elif closed and not now:
                spans.append((start, float(e["t"])))
            closed = now
        if closed:
            spans.append((start, float(t[-1])))
        return spans
    on = (np.all if every else np.any)(result.state[rows] != 0, axis=0)
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2]):
        spans.append((float(t[a]), float(t[b - 1])))
    return spans


def measurement_point(model, x: float | None = None, field: str = "W") -> dict:
    """The mesh node where :func:`psd_plot` reads the displacement.

    Default: a quarter span from the left end if that lies in an undamaged segment (one
    that joins no interface contact), else the middle of the undamaged segment nearest to
    it; segment ends (supports, junctions) are avoided. A given ``x`` is snapped to the
    nearest node of a segment containing it (undamaged ones first). Returns ``segment``,
    ``x``, ``dof`` (full index) and ``undamaged`` (bool).
    """
    stack = model.stack
    damaged = {s for c in stack.contacts if c.kind == "interface" for s in c.segments}
    segs = list(stack.segments)
    intact = [s for s in segs if s.name not in damaged]
    x0, x1 = min(s.start for s in segs), max(s.end for s in segs)

    def nearest(seg, target, interior=True):
        nodes = np.asarray(model.spaces[seg.name].x, dtype=float)
        if interior and nodes.size > 2:
            nodes = nodes[1:-1]
        return float(nodes[np.argmin(np.abs(nodes - target))])

    if x is not None:
        x = float(x)
        hit = [s for s in intact if s.start <= x <= s.end] or [s for s in segs if s.start <= x <= s.end]
        if not hit:
            raise NsfemError(f"psd: x={x} lies outside the shaft [{x0}, {x1}]")
        seg, xn = hit[0], nearest(hit[0], x, interior=False)
    else:
        target = x0 + 0.25 * (x1 - x0)
        pool = intact or segs
        inside = [s for s in pool if s.start <= target <= s.end]
        if inside:
            seg = inside[0]
            xn = nearest(seg, target)
        else:
            seg = min(pool, key=lambda s: min(abs(s.start - target), abs(s.end - target)))
            xn = nearest(seg, 0.5 * (seg.start + seg.end))
    return {"segment": seg.name, "x": xn, "dof": model.dof(seg.name, field, xn),
            "undamaged": seg.name not in damaged}


# --------------------------------------------------------------------------- plots
def hermite_refine(t: np.ndarray, x: np.ndarray, dx: np.ndarray, f_hz: float, kicks=(),
                   per_period: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """(x, x') drawn between samples as the cubic Hermite interpolant of the values and rates there,
    about ``per_period`` points per period of ``f_hz`` (an 83 Hz mode sampled every 1 ms is a 12-gon; 48 sag by 2e-3;
    the interpolant is within (w h)^4 / 384 of a harmonic, 2e-4 there, its slope within (w h)^3 / 72).
    Intervals holding an impact (a jump in x') keep their straight chord."""
    t, x, dx = (np.asarray(a, dtype=float) for a in (t, x, dx))
    if t.size < 2 or not f_hz > 0:
        return x, dx
    h = np.diff(t)
    n = np.clip(np.ceil(h * f_hz * per_period).astype(int), 1, 64)
    if np.all(n == 1):
        return x, dx
    kicks = np.asarray(sorted(kicks), dtype=float)
    xs, dxs = [x[:1]], [dx[:1]]
    for i in range(t.size - 1):
        hit = kicks.size and np.any((kicks > t[i]) & (kicks <= t[i + 1]))
        if n[i] == 1 or hit:
            xs.append(x[i + 1:i + 2])
            dxs.append(dx[i + 1:i + 2])
            continue
        s = np.arange(1, n[i] + 1) / n[i]
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
        xs.append(h00 * x[i] + h10 * h[i] * dx[i] + h01 * x[i + 1] + h11 * h[i] * dx[i + 1])
        dxs.append((d00 * x[i] + d01 * x[i + 1]) / h[i] + d10 * dx[i] + d11 * dx[i + 1])
    return np.concatenate(xs), np.concatenate(dxs)


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


def gap_plot(result, system, path) -> Path:
    """Gap over time at the middle of each delamination (bold), the other contacts of the
    delamination in thin lines, its closed intervals shaded and its impacts marked; for a crack
    its opening (bold: the larger gap of its front's two ends, drawn thin), shaded where it is
    closed (both ends) and, lighter, partly closed (one end). Gaps in mm, or in um when a panel's
    largest is below 0.01 mm."""
    groups = delamination_middles(system)
    if not groups:
        raise NoPlotData("gap: the scene has no contacts")
    if result.t.size == 0:
        raise NoPlotData("gap: the run has no samples")
    t = result.t
    impacts = result.impacts
    labels = list(system.model_contacts.labels)
    fig, axes = figure(nrows=len(groups), ncols=1, sharex=True, squeeze=False,
                       figsize=(FIGSIZE[0], max(FIGSIZE[1], 2.4 * len(groups))))
    wmin = 2e-3 * (t[-1] - t[0])  # closures often last far less than a pixel: widen them to one
    for ax, g in zip(axes[:, 0], groups):
        crack = g["kind"] == "crack"
        rows = g["indices"]
        peak = float(np.abs(result.gap[rows]).max(initial=0.0))
        scale, unit = (1e3, "mm") if peak >= 1e-5 or peak == 0.0 else (1e6, r"$\mu$m")
        for k in rows:
            if crack or k != g["middle"]:
                ax.plot(t, scale * result.gap[k], lw=0.5, color="0.65")
        if crack:
            ax.plot([], [], lw=0.5, color="0.65", label="front ends " + ", ".join(labels[k].rsplit(".", 1)[-1]
                                                                                for k in rows))
            ax.plot(t, scale * result.gap[rows].max(axis=0), lw=1.3, color="tab:blue", label="opening")
            partly = closed_intervals(result, rows, every=False)
            for a, b in partly:
                ax.axvspan(a, max(b, a + wmin), color="tab:orange", alpha=0.2, lw=0)
            if partly:
                ax.plot([], [], color="tab:orange", alpha=0.3, lw=6, label=f"one end or both closed ({len(partly)})")
            spans = closed_intervals(result, rows)
        else:
            if len(rows) > 1:
                ax.plot([], [], lw=0.5, color="0.65", label="other contacts")
            k = g["middle"]
            ax.plot(t, scale * result.gap[k], lw=1.3, color="tab:blue", label=f"x = {g['x']:.4g} m (middle)")
            spans = closed_intervals(result, k)
        ax.axhline(0.0, color="k", lw=0.6)
        for a, b in spans:
            ax.axvspan(a, max(b, a + wmin), color="tab:red", alpha=0.3, lw=0)
            ax.plot([a, max(b, a + wmin)], [0.0, 0.0], color="tab:red", lw=4, solid_capstyle="butt")
        if spans:
            ax.plot([], [], color="tab:red", alpha=0.5, lw=6,
                    label=f"{'both ends ' if crack else ''}closed ({len(spans)} intervals)")
        ti = [im["t"] for im in impacts if set(rows if crack else [g["middle"]]) & set(im.get("contacts", []))]
        if ti:
            ax.plot(ti, np.zeros(len(ti)), "v", color="tab:red", ms=5, label=f"impacts ({len(ti)})")
        ax.set_ylabel(f"{'opening' if crack else 'gap'} [{unit}]")
        a, b = g["span"]
        ax.set_title(f"{g['name']} (x = {g['x']:.4g} m): opening, the larger gap of its front's two ends" if crack
                     else f"{g['name']} ({a:.3g} to {b:.3g} m): gap at its middle", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 0].set_xlim(t[0], t[-1])
    cracks = sum(g["kind"] == "crack" for g in groups)
    fig.suptitle("Crack opening" if cracks == len(groups) else "Gap opening at the middle of the delamination"
                 + ("; crack opening" if cracks else ""), fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def psd_plot(result, system, path, x: float | None = None, field: str = "W",
             steady_from: float | None = None, f_max: float | None = None, nperseg: int | None = None) -> Path:
    """Welch PSD of the transverse displacement ``field`` (rotating frame) at a point of an
    undamaged region (:func:`measurement_point`), for t >= ``steady_from`` (default: the last
    half), log scale, with the rotation frequency and its harmonics marked; the frequency axis
    ends at ``f_max`` (default 10 x the rotation frequency, or 250 Hz, within Nyquist).

    ``nperseg`` defaults to the whole window (one Hann segment): a simulated signal has no
    noise to average out, and the forced 1x line must be told apart from the nearby free
    vibration (resolution 1 / window length)."""
    model, T = _model_and_T(system)
    if model is None:
        raise NoPlotData("psd: the system carries no finite-element model to locate a point on")
    sel = _window(result.t, steady_from)
    if sel.sum() < 8:
        raise NoPlotData("psd: fewer than 8 samples in the steady-state window")
    t = result.t[sel]
    frame = result.info.get("frame", "rotating")
    sensors = system.info.get("sensors", ()) if x is None else ()
    if sensors:
        # the first sensor, in its own frame: what the probe on the machine would give
        from ..sensors import read

        s = sensors[0]
        w = read(sensors[:1], model, _dense(T), t, result.q[:, sel], frame, result.info.get("speed_hz", 0.0),
                 result.info.get("phase_deg", 0.0))[:, 0]
        pt = {"x": s.x, "segment": s.segment, "undamaged": True}
        field, frame, label = f"{s.direction} ({s.name})", s.frame, f"sensor {s.name} at x = {s.x:.4g} m"
    else:
        pt = measurement_point(model, x, field)
        row = _dense(T[pt["dof"]]).ravel()
        w = row @ result.q[:, sel]
        label = f"{field} at x = {pt['x']:.4g} m ({pt['segment']})"
    dt, w = _uniform(t, w)
    f, P = welch_psd(w, dt, nperseg=nperseg or w.size)
    speed = _speed_hz(result, system)
    nyq = 0.5 / dt
    top = min(nyq, f_max if f_max else (10.0 * speed if speed > 0 else 250.0))
    keep = (f > 0) & (f <= top)
    fig, ax = figure(figsize=FIGSIZE)
    ax.semilogy(f[keep], P[keep], lw=1.2, color="tab:blue", label=label)
    if speed > 0:
        for h in range(1, int(top // speed) + 1):
            ax.axvline(h * speed, color="tab:red", ls=":", lw=0.9,
                       label=f"rotation {speed:g} Hz and harmonics" if h == 1 else None)
    i = int(np.argmax(np.where(keep, P, -np.inf)))
    ax.plot(f[i], P[i], "o", mfc="none", color="k", ms=8, label=f"peak {f[i]:.4g} Hz")
    ax.set_xlim(0.0, top)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD of {field} [m$^2$/Hz]")
    where = ("sensor" if sensors else "undamaged region") if pt["undamaged"] else \
        "no undamaged region: delaminated segment"
    ax.set_title(f"Power spectrum of the displacement {field} ({frame} frame), {where}\n"
                 f"t = {t[0]:.3g} to {t[-1]:.3g} s, resolution {f[1] - f[0]:.3g} Hz", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    return save(fig, path)


def loaded_contacts(result) -> list[int]:
    """Rows of the contacts that carry a force at some sample or take part in an impact."""
    m = result.gap.shape[0]
    if m == 0:
        return []
    hit = {int(k) for im in result.impacts for k in im.get("contacts", [])}
    tang = np.linalg.norm(result.tangential_force, axis=1) if result.t.size else np.zeros((m, 0))
    loaded = (np.abs(result.normal_force).max(axis=1, initial=0.0) > 0) | (tang.max(axis=1, initial=0.0) > 0)
    return sorted(hit | set(np.flatnonzero(loaded).tolist()))


def _force_series(system, rows: list[int]) -> list[tuple[str, list[int]]]:
    """(legend label, contact rows) of each line of :func:`forces_plot`: one per loaded contact, but a
    crack's loaded front ends (labels ``crack.<i>.<k>``) as one line, ``crack.<i> faces``, their forces summed (an
    end that never carries load adds nothing)."""
    labels = list(system.model_contacts.labels)
    xs = np.asarray(system.model_contacts.x, dtype=float)
    series: dict[str, list[int]] = {}
    for k in rows:
        head, _, tail = labels[k].rpartition(".")
        crack = head.startswith("crack.") and head.count(".") == 1 and tail.isdigit()
        key = f"{head} faces (x = {xs[k]:.3g} m)" if crack else f"{labels[k]} (x = {xs[k]:.3g} m)"
        series.setdefault(key, []).append(k)
    return list(series.items())


def forces_plot(result, system, path) -> Path:
    """Normal and tangential contact-force magnitudes [N] over time of the contacts that
    ever carry load, and the impacts as stems of their impulses [N s]. A crack's front ends
    are one line: the force across its faces (their normal forces summed, and impulses per
    impact)."""
    if result.gap.shape[0] == 0:
        raise NoPlotData("forces: the scene has no contacts")
    rows = loaded_contacts(result)
    if not rows:
        raise NoPlotData("forces: no contact carried load or took an impact during the run")
    t = result.t
    series = _force_series(system, rows)
    fig, (ax, bx) = figure(nrows=2, ncols=1, sharex=True, figsize=FIGSIZE, gridspec_kw={"height_ratios": [3, 2]})
    colors = [f"C{i % 10}" for i in range(len(series))]
    friction = False
    for (name, ks), color in zip(series, colors):
        normal = result.normal_force[ks].sum(axis=0)
        ax.plot(t, normal, lw=1.0, color=color, label=name)
        on = normal > 0  # closures shorter than output_dt show as single samples
        ax.plot(t[on], normal[on], ".", ms=4, color=color)
        tg = np.linalg.norm(result.tangential_force[ks], axis=1).sum(axis=0)
        if np.any(tg > 0):
            friction = True
            ax.plot(t, tg, lw=0.9, ls="--", color=color)
    if friction:
        ax.plot([], [], ls="--", color="k", lw=0.9, label="tangential |lam_T|")
    ax.set_ylabel("contact force [N]")
    ax.set_title("Normal force (solid)" + (" and tangential force magnitude (dashed)" if friction else "")
                 + " at the output times", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2 if len(series) > 4 else 1)
    n_imp = 0
    for (_, ks), color in zip(series, colors):
        ti, pi = [], []
        for im in result.impacts:
            mine = [p for c, p in zip(im.get("contacts", []), im.get("impulse_Ns", [])) if int(c) in ks]
            if mine:
                ti.append(im["t"])
                pi.append(sum(mine))
        if ti:
            n_imp += len(ti)
            ml, sl, bl = bx.stem(ti, pi, basefmt=" ")
            ml.set_color(color)
            ml.set_markersize(4)
            sl.set_color(color)
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_ylabel("impulse [N s]")
    bx.set_xlabel("time [s]")
    bx.set_title(f"Impacts: {n_imp} impulses" if n_imp else "no impacts", fontsize=9)
    bx.grid(True, alpha=0.3)
    if t.size:
        bx.set_xlim(t[0], t[-1])
    fig.tight_layout()
    return save(fig, path)


PLOT_FUNCTIONS = {"phase": phase_plot, "gap": gap_plot, "psd": psd_plot, "forces": forces_plot}


def write_plots(result, system, out_dir, names=RESULT_PLOTS, warn=None) -> list[Path]:
    """Write ``<out_dir>/<name>.png`` for each name in ``names`` (``output.plots``) and return
    the paths written. ``campbell`` is ignored here (it needs a speed sweep, see
    ``nsfem campbell``); a plot without data is skipped and its reason passed to
    ``warn(text)`` (default: :func:`warnings.warn`); an unknown name raises NsfemError."""
    unknown = [n for n in names if n not in PLOT_FUNCTIONS and n != "campbell"]
    if unknown:
        raise NsfemError(f"output.plots: unknown plot(s) {', '.join(map(repr, unknown))} "
                         f"(known: {', '.join(RESULT_PLOTS)}, campbell)")
    out_dir = Path(out_dir)
    written = []
    for name in dict.fromkeys(names):
        if name == "campbell":
            continue
        try:
            written.append(PLOT_FUNCTIONS[name](result, system, out_dir / f"{name}.png"))
        except NoPlotData as exc:
            msg = f"plot {name!r} skipped: {exc}"
            if warn is None:
                warnings.warn(msg, stacklevel=2)
            else:
                warn(msg)
    return written
