"""psd.png: Welch PSD of the transverse displacement at a measurement point."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save
from .data import FIGSIZE, NoPlotData, _dense, _model_and_T, _speed_hz, _uniform, _window, measurement_point, welch_psd

#: decades of PSD drawn below its peak: a displacement PSD 10^-12 below the peak is 10^-6 of the peak's
#: amplitude, the most a probe's dynamic range resolves; lower lies round-off and window leakage
PSD_DECADES = 12


def psd_plot(result, system, path, x: float | None = None, field: str = "W",
             steady_from: float | None = None, f_max: float | None = None, nperseg: int | None = None) -> Path:
    """Welch PSD of the transverse displacement ``field`` (rotating frame) at a point of an
    undamaged region (:func:`measurement_point`), for t >= ``steady_from`` (default: the last
    half), log scale down to :data:`PSD_DECADES` decades below the peak, with the rotation frequency and
    its harmonics marked; the frequency axis ends at ``f_max`` (default 10 x the rotation frequency, or
    250 Hz, within Nyquist).

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
        from ..sensors import read, speed_table

        s = sensors[0]
        w = read(sensors[:1], model, _dense(T), t, result.q[:, sel], frame, result.info.get("speed_hz", 0.0),
                 result.info.get("phase_deg", 0.0), result.info.get("ramp_to_hz"), result.info.get("ramp_s", 0.0),
                 speed_table(result.info))[:, 0]
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
    band = _speed_band(result.info, t)
    if band is not None:
        speed = max(band)
    nyq = 0.5 / dt
    top = min(nyq, f_max if f_max else (10.0 * speed if speed > 0 else 250.0))
    keep = (f > 0) & (f <= top)
    fig, ax = figure(figsize=FIGSIZE)
    ax.semilogy(f[keep], P[keep], lw=1.2, color="tab:blue", label=label)
    band = _speed_band(result.info, t)
    if band is not None:    # a run-up: the speeds the window sweeps, and their harmonics' bands while apart
        lo, hi = min(band), max(band)
        last = max(1, min(int(top // hi), int(lo // (hi - lo))))
        for h in range(1, last + 1):
            ax.axvspan(h * lo, h * hi, color="tab:red", alpha=0.12, lw=0,
                       label=f"rotation {band[0]:.4g} -> {band[1]:.4g} Hz" + (" and harmonics" if last > 1 else "")
                       if h == 1 else None)
    elif speed > 0:
        for h in range(1, int(top // speed) + 1):
            ax.axvline(h * speed, color="tab:red", ls=":", lw=0.9,
                       label=f"rotation {speed:g} Hz and harmonics" if h == 1 else None)
    i = int(np.argmax(np.where(keep, P, -np.inf)))
    ax.plot(f[i], P[i], "o", mfc="none", color="k", ms=8, label=f"peak {f[i]:.4g} Hz")
    ax.set_xlim(0.0, top)
    if P[i] > 0:  # below 12 decades under the peak lies round-off and window leakage, not the machine
        ax.set_ylim(P[i] * 10.0 ** -PSD_DECADES, P[i] * 10.0)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD of {field} [m$^2$/Hz]")
    where = ("sensor" if sensors else "undamaged region") if pt["undamaged"] else \
        "no undamaged region: delaminated segment"
    ax.set_title(f"Power spectrum of the displacement {field} ({frame} frame), {where}\n"
                 f"t = {t[0]:.3g} to {t[-1]:.3g} s, resolution {f[1] - f[0]:.3g} Hz", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3, frameon=False)
    fig.tight_layout()
    return save(fig, path)


def _speed_band(info: dict, t: np.ndarray) -> tuple[float, float] | None:
    """(speed at t[0], speed at t[-1]) [Hz] of a run-up's window (a ramp or a speed table in the run's info),
    None at constant speed."""
    from ..scene.parts import Rotation
    from ..sensors import speed_table

    table = speed_table(info)
    if table is not None:
        rot = Rotation(float(table[1][0]), 0.0, 0.0, "inertial", speed_table_s=table[0], speed_table_hz=table[1])
    elif info.get("ramp_to_hz") is not None and info.get("ramp_s"):
        rot = Rotation(float(info.get("speed_hz", 0.0)), 0.0, 0.0, "inertial", float(info["ramp_to_hz"]),
                       float(info["ramp_s"]))
    else:
        return None
    a, b = float(rot.speed_at(float(t[0]))), float(rot.speed_at(float(t[-1])))
    return None if a == b else (a, b)
