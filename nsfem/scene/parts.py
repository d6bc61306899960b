"""Typed parts of a validated scene: one frozen dataclass per option table.

:func:`parts` builds them once, after validation, from the tree :func:`~nsfem.scene.validate.validate_tree`
returns (every key present, values of the right kind and range); a :class:`~nsfem.scene.load.Scene`
carries them as attributes (``scene.rotation``, ``scene.damping``, ...), and each layer takes the part
it needs. Their fields are the table's keys, lists as tuples. The geometry tables become the
:class:`~nsfem.stack.BeamStack` (``scene.stack``), the sensors :class:`~nsfem.sensors.Sensor`
(``scene.sensors``).

>>> from nsfem.scene import load_scene
>>> scene = load_scene(None, ["rotation.speed_hz=12", "reduction.modes=8"])
>>> scene.rotation.speed_hz, scene.reduction
(12.0, ReductionOptions(method='craig-bampton', modes=8))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SceneError


@dataclass(frozen=True)
class Rotation:
    """``[rotation]``: speed [Hz], gravity [m/s^2] along inertial -Z, the rotating frame's angle at
    t = 0 [deg], the frame of the coordinates (``rotating`` or ``inertial``) and a run-up or coast-down:
    the speed ramps linearly from ``speed_hz`` to ``ramp_to_hz`` over ``ramp_s`` seconds and stays there
    (``ramp_to_hz`` None: constant speed, the special case every method integrates).

    The speed profile Omega(t) [rad/s], its rate and the rotation angle theta(t) = int_0^t Omega (the
    phase not included) are :meth:`omega_at`, :meth:`acceleration_at` and :meth:`angle_at`.

    >>> r = Rotation(10.0, 0.0, 0.0, "inertial", ramp_to_hz=30.0, ramp_s=2.0)
    >>> r.speed_at(1.0), r.speed_at(5.0), round(r.angle_at(2.0) / (2 * math.pi), 12)
    (20.0, 30.0, 40.0)
    """

    speed_hz: float
    gravity: float
    phase_deg: float
    frame: str
    ramp_to_hz: float | None = None
    ramp_s: float = 0.0

    def __post_init__(self):
        for key in ("speed_hz", "ramp_to_hz", "ramp_s"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value >= 0.0):
                raise SceneError(f"rotation.{key}", f"must be a finite number >= 0, got {value}")
        if self.ramp_to_hz is None:
            if self.ramp_s:
                raise SceneError("rotation.ramp_s", f"{self.ramp_s:g} s given without rotation.ramp_to_hz (the "
                                 "speed the ramp ends at)")
            return
        if not self.ramp_s > 0.0:
            raise SceneError("rotation.ramp_s", f"must be > 0 with rotation.ramp_to_hz = {self.ramp_to_hz:g} (the "
                             f"ramp's duration in seconds), got {self.ramp_s:g}")

    @property
    def ramped(self) -> bool:
        """Whether the speed changes in time."""
        return self.ramp_to_hz is not None and self.ramp_to_hz != self.speed_hz

    @property
    def alpha(self) -> float:
        """The ramp's angular acceleration [rad/s^2] (negative: coast-down; 0 at constant speed)."""
        if not self.ramped:
            return 0.0
        return 2.0 * math.pi * (self.ramp_to_hz - self.speed_hz) / self.ramp_s

    def speed_at(self, t):
        """Omega(t) / (2 pi) [Hz] at the times ``t`` (a float for a scalar, else an array): linear over
        [0, ramp_s] from speed_hz to ramp_to_hz, constant after."""
        t = np.asarray(t, dtype=float)
        out = self.speed_hz + 0.0 * t
        if self.ramped:
            out = out + (self.ramp_to_hz - self.speed_hz) * (np.clip(t, 0.0, self.ramp_s) / self.ramp_s)
        return float(out) if out.ndim == 0 else out

    def omega_at(self, t):
        """Omega(t) [rad/s] (:meth:`speed_at`)."""
        return 2.0 * math.pi * self.speed_at(t)

    def acceleration_at(self, t):
        """Omega'(t) [rad/s^2]: the ramp's alpha on [0, ramp_s), 0 after."""
        t = np.asarray(t, dtype=float)
        out = np.where(t < self.ramp_s, self.alpha, 0.0) if self.ramped else 0.0 * t
        return float(out) if out.ndim == 0 else out

    def angle_at(self, t):
        """theta(t) = int_0^t Omega [rad] (without ``phase_deg``), in closed form."""
        t = np.asarray(t, dtype=float)
        w0 = 2.0 * math.pi * self.speed_hz
        if self.ramped:
            s = np.clip(t, 0.0, self.ramp_s)
            out = w0 * t + self.alpha * (s * s / 2.0 + s * (t - s))
        else:
            out = w0 * t
        return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class Damping:
    """``[damping]``: internal Rayleigh damping (alpha [1/s], beta [s]) and external viscous damping
    per unit length [N s/m^2]."""

    rayleigh: tuple[float, float]
    external: float


@dataclass(frozen=True)
class MeshOptions:
    """``[mesh]``: element count of a generated mesh, the mesh file (resolved against the scene's
    folder; None: generate) and the axial element (``P1`` or ``P2``)."""

    elements: int
    file: Path | None
    axial: str


@dataclass(frozen=True)
class ReductionOptions:
    """``[reduction]``: method (``none``, ``modal``, ``craig-bampton``) and kept normal modes."""

    method: str
    modes: int


@dataclass(frozen=True)
class Initial:
    """``[initial]``: state (``rest`` or ``stationary``) and uniform velocity (u1, u2, u3) [m/s]."""

    state: str
    velocity: tuple[float, float, float]


@dataclass(frozen=True)
class Simulation:
    """``[simulation]``: the integrator and its settings (see ``docs/scene.md``)."""

    method: str
    t_end: float
    output_dt: float
    rk_solver: str
    rtol: float
    atol: float
    penalty_stiffness: float
    penalty_factor: float
    stiff_solver: str
    moreau_step: float
    moreau_theta: float


@dataclass(frozen=True)
class Output:
    """``[output]``: output folder (relative to the working directory), VTU every N output steps
    (0: none) and the PNG plots."""

    dir: Path
    vtu_every: int
    plots: tuple[str, ...]


def parts(tree: dict, base: Path) -> dict[str, Any]:
    """The typed parts of a validated tree, by attribute name; ``base``: the folder ``mesh.file`` is
    relative to."""
    mesh = tree["mesh"]
    out = tree["output"]
    return {
        "title": tree["title"],
        "rotation": Rotation(**tree["rotation"]),
        "damping": Damping(tuple(tree["damping"]["rayleigh"]), tree["damping"]["external"]),
        "mesh_options": MeshOptions(mesh["elements"], base / mesh["file"] if mesh["file"] else None, mesh["axial"]),
        "reduction": ReductionOptions(**tree["reduction"]),
        "initial": Initial(tree["initial"]["state"], tuple(tree["initial"]["velocity"])),
        "simulation": Simulation(**tree["simulation"]),
        "output": Output(Path(out["dir"]), out["vtu_every"], tuple(out["plots"])),
    }
