"""runup.png: a run-up's (or coast-down's) whirl amplitude against the instantaneous speed, with the steady
unbalance response (:func:`nsfem.analysis.response.harmonic_response`) drawn beside it as the slow limit."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save

#: speeds of the steady response drawn over the ramp's range
STEADY_SPEEDS = 400


def whirl_amplitudes(values: np.ndarray, sensors) -> tuple[list[str], np.ndarray]:
    """(labels, amplitudes (len(t), k)): per orbit (a y- and a z-probe at one x in one frame) the whirl radius
    sqrt(y^2 + z^2), the envelope of a circular whirl; every other probe its |signal|."""
    from .sensors import orbit_pairs

    pairs = orbit_pairs(sensors)
    used = {i for p in pairs for i in p}
    labels, cols = [], []
    for i, j in pairs:
        labels.append(f"orbit {sensors[i].name}/{sensors[j].name}")
        cols.append(np.hypot(values[:, i], values[:, j]))
    for k, s in enumerate(sensors):
        if k not in used:
            labels.append(f"|{s.name}|")
            cols.append(np.abs(values[:, k]))
    return labels, np.column_stack(cols) if cols else np.zeros((values.shape[0], 0))


def runup_plot(path: str | Path, speeds_hz: np.ndarray, values: np.ndarray, sensors, steady_speeds_hz=None,
               steady: np.ndarray | None = None, title: str = "", rings=()) -> Path:
    """The run's amplitudes (:func:`whirl_amplitudes`) against the speed at each output time [Hz], the steady
    harmonic response's amplitude per probe (``steady``: (len(steady_speeds_hz), probes), one curve per orbit from
    its y probe) dashed beside them, and each stator ring's clearance (``rings``: [(x, clearance)]) as a line."""
    speeds = np.asarray(speeds_hz, dtype=float)
    labels, amp = whirl_amplitudes(np.asarray(values, dtype=float), sensors)
    fig, ax = figure(figsize=(8.4, 4.8), layout="constrained")
    for k, label in enumerate(labels):
        ax.plot(speeds, amp[:, k] * 1e3, lw=0.9, label=f"{label}, run")
    if steady is not None and steady_speeds_hz is not None:
        from .sensors import orbit_pairs

        pairs = orbit_pairs(sensors)
        shown = [i for i, _ in pairs] + [k for k in range(len(sensors)) if all(k not in p for p in pairs)]
        for n, k in enumerate(shown):
            ax.plot(steady_speeds_hz, np.asarray(steady)[:, k] * 1e3, ls="--", lw=1.0, color=f"C{n}",
                    label=f"{labels[n]}, steady (harmonic solve)")
    for x, c in rings:
        ax.axhline(c * 1e3, color="0.4", lw=0.8, ls=":", label=f"seal clearance at x = {x:g} m")
    ax.set_xlabel("rotor speed [Hz]")
    ax.set_ylabel("whirl amplitude [mm]")
    ax.grid(True, lw=0.3)
    # below the axes: a run-up's curves fill the plot anywhere a legend inside could sit
    fig.legend(fontsize="small", loc="outside lower center", ncols=2)
    up = speeds[-1] >= speeds[0]
    ax.set_title((title + "\n" if title else "") + ("run-up" if up else "coast-down")
                 + f" {speeds[0]:g} -> {speeds[-1]:g} Hz", fontsize="medium")
    return save(fig, path)


def scene_runup_plot(path: str | Path, scene, result, system, values: np.ndarray) -> Path:
    """:func:`runup_plot` of a run of ``scene`` (its sensor ``values``), with its steady response over the ramp's
    speeds (the scene's model and reduction in ``system.info``)."""
    from ..analysis.response import harmonic_response
    from ..fem.rotating import rotor_operators
    from .sensors import stator_rings

    rot = scene.rotation
    speeds = np.atleast_1d(rot.speed_at(result.t))
    lo, hi = float(min(speeds.min(), rot.speed_hz)), float(max(speeds.max(), rot.speed_hz))
    grid = np.linspace(lo, hi, STEADY_SPEEDS) if hi > lo else None
    steady = None
    if grid is not None:
        model, red = system.info["model"], system.info["reduction"]
        ops = rotor_operators(model, red.T)
        steady = harmonic_response(ops, scene.sensors, model, grid, rot, scene.damping).amplitude_m
    return runup_plot(path, speeds, values, scene.sensors, grid, steady, scene.title, stator_rings(system))
