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
    t = 0 [deg], the frame of the coordinates (``rotating`` or ``inertial``) and a speed that changes in time:
    a linear ramp from ``speed_hz`` to ``ramp_to_hz`` over ``ramp_s`` seconds, kept after, or a piecewise-linear
    table (``speed_table_s``, ``speed_table_hz``: from t = 0, its first speed ``speed_hz``, its last kept after).
    Neither: constant speed, the special case every method integrates.

    The speed profile Omega(t) [rad/s], its rate and the rotation angle theta(t) = int_0^t Omega (the
    phase not included) are :meth:`omega_at`, :meth:`acceleration_at` and :meth:`angle_at`.

    >>> r = Rotation(10.0, 0.0, 0.0, "inertial", ramp_to_hz=30.0, ramp_s=2.0)
    >>> r.speed_at(1.0), r.speed_at(5.0), round(r.angle_at(2.0) / (2 * math.pi), 12)
    (20.0, 30.0, 40.0)
    >>> table = Rotation(10.0, 0.0, 0.0, "inertial", speed_table_s=(0, 2, 3), speed_table_hz=(10, 30, 0))
    >>> table.speed_at(2.5), round(table.angle_at(4.0) / (2 * math.pi), 12)
    (15.0, 55.0)
    """

    speed_hz: float
    gravity: float
    phase_deg: float
    frame: str
    ramp_to_hz: float | None = None
    ramp_s: float = 0.0
    speed_table_s: tuple = ()
    speed_table_hz: tuple = ()

    def __post_init__(self):
        for key in ("speed_hz", "ramp_to_hz", "ramp_s"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value >= 0.0):
                raise SceneError(f"rotation.{key}", f"must be a finite number >= 0, got {value}")
        ts, hz = tuple(float(x) for x in self.speed_table_s), tuple(float(x) for x in self.speed_table_hz)
        object.__setattr__(self, "speed_table_s", ts)
        object.__setattr__(self, "speed_table_hz", hz)
        if ts or hz:
            self._check_table(ts, hz)
            return
        if self.ramp_to_hz is None:
            if self.ramp_s:
                raise SceneError("rotation.ramp_s", f"{self.ramp_s:g} s given without rotation.ramp_to_hz (the "
                                 "speed the ramp ends at)")
            return
        if not self.ramp_s > 0.0:
            raise SceneError("rotation.ramp_s", f"must be > 0 with rotation.ramp_to_hz = {self.ramp_to_hz:g} (the "
                             f"ramp's duration in seconds), got {self.ramp_s:g}")

    def _check_table(self, ts: tuple, hz: tuple) -> None:
        if self.ramp_to_hz is not None or self.ramp_s:
            raise SceneError("rotation.speed_table_s", "give a ramp (ramp_to_hz, ramp_s) or a speed table "
                             "(speed_table_s, speed_table_hz), not both")
        if len(ts) != len(hz) or len(ts) < 2:
            raise SceneError("rotation.speed_table_hz", f"the table needs as many speeds as times, two or more "
                             f"(got {len(ts)} times, {len(hz)} speeds)")
        for k, (a, b) in enumerate(zip(ts, hz)):
            if not (math.isfinite(a) and math.isfinite(b)):
                raise SceneError(f"rotation.speed_table_{'s' if not math.isfinite(a) else 'hz'}.{k}",
                                 f"must be finite, got {a if not math.isfinite(a) else b}")
            if b < 0.0:
                raise SceneError(f"rotation.speed_table_hz.{k}", f"must be >= 0 Hz, got {b:g}")
        if ts[0] != 0.0:
            raise SceneError("rotation.speed_table_s.0", f"the table starts at t = 0, got {ts[0]:g} s")
        for k in range(1, len(ts)):
            if not ts[k] > ts[k - 1]:
                raise SceneError(f"rotation.speed_table_s.{k}", f"the times must increase strictly: {ts[k]:g} s "
                                 f"follows {ts[k - 1]:g} s")
        if hz[0] != self.speed_hz:
            raise SceneError("rotation.speed_hz", f"{self.speed_hz:g} Hz differs from the table's first speed "
                             f"speed_table_hz.0 = {hz[0]:g} Hz: give speed_hz = {hz[0]:g} (the speed at t = 0)")

    @property
    def knots(self) -> tuple[np.ndarray, np.ndarray]:
        """(times [s], speeds [Hz]) of the piecewise-linear profile (one knot: constant speed)."""
        if self.speed_table_s:
            return np.array(self.speed_table_s), np.array(self.speed_table_hz)
        if self.ramp_to_hz is not None and self.ramp_to_hz != self.speed_hz:
            return np.array([0.0, self.ramp_s]), np.array([self.speed_hz, self.ramp_to_hz])
        return np.array([0.0]), np.array([self.speed_hz])

    @property
    def ramped(self) -> bool:
        """Whether the speed changes in time."""
        return bool(np.ptp(self.knots[1]) > 0.0)

    @property
    def max_speed_hz(self) -> float:
        return float(np.max(self.knots[1]))

    def record(self) -> dict:
        """The profile's keys as a run's info and JSON carry them (empty at constant speed)."""
        if self.speed_table_s:
            return {"speed_table_s": list(self.speed_table_s), "speed_table_hz": list(self.speed_table_hz)}
        if self.ramp_to_hz is not None:
            return {"ramp_to_hz": self.ramp_to_hz, "ramp_s": self.ramp_s}
        return {}

    def describe(self) -> str:
        """'18 -> 38 Hz in 1 s' (a ramp) or 'a table of 3 speeds, 10 to 30 Hz, over 3 s'."""
        ts, hz = self.knots
        if self.speed_table_s:
            return f"a table of {ts.size} speeds, {hz.min():g} to {hz.max():g} Hz, over {ts[-1]:g} s"
        return f"{hz[0]:g} -> {hz[-1]:g} Hz in {ts[-1]:g} s"

    @property
    def alpha(self) -> float:
        """A ramp's angular acceleration [rad/s^2] (negative: coast-down; 0 at constant speed)."""
        ts, hz = self.knots
        return 2.0 * math.pi * (hz[-1] - hz[0]) / ts[-1] if ts.size > 1 else 0.0

    def speed_at(self, t):
        """Omega(t) / (2 pi) [Hz] at the times ``t`` (a float for a scalar, else an array): linear between the
        knots, the first speed before them and the last after."""
        ts, hz = self.knots
        out = np.interp(np.asarray(t, dtype=float), ts, hz)
        return float(out) if out.ndim == 0 else out

    def omega_at(self, t):
        """Omega(t) [rad/s] (:meth:`speed_at`)."""
        return 2.0 * math.pi * self.speed_at(t)

    def acceleration_at(self, t):
        """Omega'(t) [rad/s^2]: the slope of the segment t lies in (from its start on), 0 outside the knots."""
        ts, hz = self.knots
        t = np.asarray(t, dtype=float)
        if ts.size < 2:
            out = 0.0 * t
        else:
            slope = np.append(2.0 * math.pi * np.diff(hz) / np.diff(ts), 0.0)
            k = np.searchsorted(ts, t, side="right") - 1
            out = np.where(k >= 0, slope[np.clip(k, 0, ts.size - 1)], 0.0)
        return float(out) if out.ndim == 0 else out

    def angle_at(self, t):
        """theta(t) = int_0^t Omega [rad] (without ``phase_deg``), in closed form (exact for the linear segments)."""
        ts, hz = self.knots
        t = np.asarray(t, dtype=float)
        w = 2.0 * math.pi * hz
        if ts.size < 2:
            out = w[0] * t
        else:
            slope = np.append(np.diff(w) / np.diff(ts), 0.0)
            start = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(ts))])
            k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ts.size - 1)
            d = t - ts[k]
            out = np.where(t < 0.0, w[0] * t, start[k] + w[k] * d + 0.5 * slope[k] * d * d)
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
