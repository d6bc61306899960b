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

from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Rotation:
    """``[rotation]``: speed [Hz], gravity [m/s^2] along inertial -Z, the rotating frame's angle at
    t = 0 [deg] and the frame of the coordinates (``rotating`` or ``inertial``)."""

    speed_hz: float
    gravity: float
    phase_deg: float
    frame: str


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
