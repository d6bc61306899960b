"""Displacement probes (``[[sensor]]``, design section 8): what a proximity probe on the machine reads.

A sensor reads the lateral displacement of the shaft's axis at ``x`` along ``direction`` (+-y, +-z) in
``frame``: the inertial frame (a probe fixed on the casing) or the rotating one (a telemetry probe on
the shaft). The displacement between nodes is the Hermite interpolation of the element's values and
slopes, so a sensor needs no mesh node and adding one changes nothing else. Inside a delamination it
reads the ``layer`` given (upper: the sub-beam on top).

>>> from nsfem import load_scene, build_model
>>> scene = load_scene(None, ['sensor.0.name="probe"', "sensor.0.x=0.05", 'sensor.0.direction="+z"'])
>>> [s.name for s in scene.sensors], scene.sensors[0].frame
(['probe'], 'inertial')
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .atomic import write_text_atomic
from .errors import SceneError
from .fem import timoshenko

DIRECTIONS = ("+y", "+z", "-y", "-z")
SENSOR_FRAMES = ("inertial", "rotating")
LAYERS = ("", "upper", "lower")


@dataclass(frozen=True)
class Sensor:
    """A validated probe: its column name, position, direction, frame and the segment it reads."""

    name: str
    x: float
    direction: str
    frame: str
    segment: str


def sensors_from_scene(tree: dict, stack) -> tuple[Sensor, ...]:
    """The scene's ``[[sensor]]`` tables, checked against the stack (position, layer, unique names)."""
    out, names = [], set()
    for i, s in enumerate(tree.get("sensor", [])):
        key = f"sensor.{i}"
        name = s["name"] or f"sensor_{i}"
        if name in names or name == "t":
            raise SceneError(f"{key}.name", f"{name!r} is taken (names are sensors.csv's column heads, after 't')")
        if any(c in name for c in ',"\n\r'):
            raise SceneError(f"{key}.name", f"{name!r} holds a comma, quote or line break (a CSV column head)")
        if name != name.strip() or not name.isprintable():
            # a CSV reader strips a column head's blanks: sensors.csv must name the sensor as the scene does
            raise SceneError(f"{key}.name", f"{name!r} begins or ends with a blank or holds a control character "
                             "(a CSV column head: nsfem fit reads sensors.csv back by these names)")
        names.add(name)
        x = s["x"]
        at = [g for g in stack.segments if g.start <= x <= g.end]
        if not at:
            lo, hi = min(g.start for g in stack.segments), max(g.end for g in stack.segments)
            raise SceneError(f"{key}.x", f"x={x} lies outside the rotor [{lo}, {hi}]")
        inside = [g for g in at if g.start < x < g.end]
        if len(inside) > 1:
            if not s["layer"]:
                raise SceneError(f"{key}.layer", f"x={x} lies in a delamination: choose upper or lower")
            pick = max if s["layer"] == "upper" else min
            seg = pick(inside, key=lambda g: g.offset[1])
        else:
            if s["layer"]:
                raise SceneError(f"{key}.layer", f"x={x} lies on the intact shaft: a layer is chosen only inside a "
                                 "delamination")
            seg = (inside or at)[0]
        out.append(Sensor(name, x, s["direction"], s["frame"], seg.name))
    return tuple(out)


def hermite_row(model, segment: str, field: str, x: float) -> sp.csr_matrix:
    """1 x n_full row that reads field V or W at x: the cubic Hermite interpolation of the element's
    end values and slopes (exact for the finite-element field); with Timoshenko's shear the element's
    displacement functions N_v of its end values and rotations (:func:`nsfem.fem.timoshenko.shape`)."""
    space = model.spaces[segment]
    order = np.argsort(space.x)                      # a line mesh's elements join neighbouring nodes
    nodes = np.asarray(space.x, dtype=float)[order]
    e = int(np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2))
    h = nodes[e + 1] - nodes[e]
    s = (x - nodes[e]) / h
    if space.phi:
        k = min(order[e], order[e + 1])                 # the element's index in the segment's assembly
        weights = timoshenko.shape(np.array([s]), np.array([h]), space.shear(field)[k:k + 1])[0].ravel()
    else:
        weights = (1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, h * (s**3 - s**2))
    nd = space.bending.nodal_dofs
    a, b = order[e], order[e + 1]
    local = (nd[0, a], nd[1, a], nd[0, b], nd[1, b])
    cols = space.dofs[field][list(local)]
    return sp.csr_matrix((weights, (np.zeros(4, dtype=int), cols)), shape=(1, model.n_full))


def speed_table(info: dict) -> tuple | None:
    """(times, speeds) of a run's speed table from its info (None: no table)."""
    if info.get("speed_table_s"):
        return tuple(info["speed_table_s"]), tuple(info["speed_table_hz"])
    return None


def frame_angle(t, speed_hz: float, phase_deg: float = 0.0, ramp_to_hz: float | None = None,
                ramp_s: float = 0.0, table: tuple | None = None) -> np.ndarray:
    """The rotating frame's angle theta(t) + phi [rad] at the times ``t``: Omega t + phi at constant speed,
    the integral of a run-up's Omega(t) (``ramp_to_hz``, ``ramp_s``, or ``table`` = (times, speeds):
    :class:`~nsfem.scene.parts.Rotation`)."""
    from .scene.parts import Rotation

    if table is not None:
        ramp = Rotation(float(table[1][0]), 0.0, phase_deg, "inertial", speed_table_s=table[0],
                        speed_table_hz=table[1])
    else:
        ramp = Rotation(speed_hz, 0.0, phase_deg, "inertial", ramp_to_hz, ramp_s if ramp_to_hz is not None else 0.0)
    return np.asarray(ramp.angle_at(np.asarray(t, dtype=float)), dtype=float) + math.radians(phase_deg)


def read(sensors, model, basis, t: np.ndarray, q: np.ndarray, frame: str, speed_hz: float,
         phase_deg: float = 0.0, ramp_to_hz: float | None = None, ramp_s: float = 0.0,
         table: tuple | None = None) -> np.ndarray:
    """Sensor signals (len(t), len(sensors)) from reduced coordinates q (n, len(t)) with q_full = basis q,
    computed in the scene's ``frame``; a sensor in the other frame sees them turned by theta(t) + phi
    (:func:`frame_angle`: Omega t + phi, or a run-up's integral of Omega(t))."""
    out = np.empty((np.size(t), len(sensors)))
    theta = frame_angle(t, speed_hz, phase_deg, ramp_to_hz, ramp_s, table)
    spinning = bool(speed_hz) or bool(ramp_to_hz) or (table is not None and any(table[1]))
    for k, s in enumerate(sensors):
        v, w = ((hermite_row(model, s.segment, f, s.x) @ basis) @ q for f in ("V", "W"))
        v, w = np.ravel(v), np.ravel(w)
        if s.frame != frame and spinning:
            # rotating -> inertial turns by +theta, inertial -> rotating by -theta
            sign = 1.0 if frame == "rotating" else -1.0
            c, sn = np.cos(theta), sign * np.sin(theta)
            v, w = c * v - sn * w, sn * v + c * w
        value = v if s.direction[1] == "y" else w
        out[:, k] = -value if s.direction[0] == "-" else value
    return out


def write_csv(path: str | Path, t: np.ndarray, sensors, values: np.ndarray) -> Path:
    """sensors.csv: a column ``t`` [s], then one per sensor [m] (written atomically)."""
    head = ",".join(["t", *(s.name for s in sensors)])
    rows = [",".join(repr(float(x)) for x in (ti, *vals)) for ti, vals in zip(t, values)]
    return write_text_atomic(path, "\n".join([head, *rows]) + "\n")
