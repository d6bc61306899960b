"""Whirl orbits of damped modes along the shaft (``nsfem modes --speed HZ --png FILE``).

One panel per mode (the first :data:`PANELS`): at each node the orbit Re((V, W) e^{i t}) of the mode's
normalized shape (:class:`nsfem.analysis.damped.DampedModes`, largest semi-major axis 1) drawn as an
ellipse in the y-z plane at its position x along the shaft, the shaft's line at phase 0 through the
orbits, a dot where each orbit starts and the panel coloured by whirl (forward blue, backward red).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import figure, save

#: modes drawn
PANELS = 4
#: colour per whirl
COLOURS = {"forward": "tab:blue", "backward": "tab:red", "planar": "tab:gray", "axial": "tab:green"}


def whirl_orbits_plot(path: str | Path, modes, title: str = "") -> Path:
    """The whirl orbits of the first :data:`PANELS` modes of ``modes`` along the shaft."""
    k = max(1, min(PANELS, len(modes.whirl)))
    rows = (k + 1) // 2
    fig, axes = figure(nrows=rows, ncols=2 if k > 1 else 1, figsize=(11.0 if k > 1 else 6.5, 3.4 * rows + 0.7),
                       squeeze=False, subplot_kw={"projection": "3d"})
    t = np.linspace(0.0, 2 * np.pi, 49)
    phase = np.exp(1j * t)
    x = modes.x_m
    for i, ax in enumerate(axes.ravel()):
        if i >= len(modes.whirl) or modes.whirl[i] == "axial":
            ax.set_axis_off()
            ax.text2D(0.5, 0.5, "no oscillating mode" if i >= len(modes.whirl) else
                      f"mode {i + 1}: {modes.frequencies_hz[i]:.4g} Hz, axial (no lateral orbit)", ha="center",
                      transform=ax.transAxes)
            continue
        ax.set_box_aspect((3.0, 1.0, 1.0))
        ax.view_init(elev=22, azim=-62)
        S = modes.shapes[i]
        colour = COLOURS[modes.whirl[i]]
        for j in range(x.size):
            orbit = np.real(S[j][:, None] * phase[None, :])
            ax.plot(np.full(t.size, x[j]), orbit[0], orbit[1], color=colour, lw=0.8)
        start = S.real
        ax.plot(x, start[:, 0], start[:, 1], color="k", lw=1.2)
        ax.scatter(x, start[:, 0], start[:, 1], color="k", s=6)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [-]")
        ax.set_zlabel("z [-]")
        ax.set_ylim(-1.05, 1.05)
        ax.set_zlim(-1.05, 1.05)
        ax.set_yticks([-1.0, 0.0, 1.0])
        ax.set_zticks([-1.0, 0.0, 1.0])
        ax.set_title(f"mode {i + 1}: {modes.frequencies_hz[i]:.4g} Hz, {modes.whirl[i]}, log dec "
                     f"{modes.log_decrements[i]:.3g}", fontsize=9, color=colour)
    fig.suptitle(f"{title}\nwhirl orbits at {modes.speed_hz:g} Hz ({modes.frame} frame; amplitudes normalized "
                 "to a largest orbit of 1; line: the shaft at phase 0)", fontsize=9)
    return save(fig, path)


__all__ = ["whirl_orbits_plot"]
