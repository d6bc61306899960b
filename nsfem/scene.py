"""Scene files (TOML): defaults, ``--set`` overrides, validation, translation to a BeamStack.

A scene is read, overridden, checked against :data:`SCHEMA` (unknown keys, types,
ranges, NaN/inf) and cross-checked (delaminations inside the shaft, contact points
inside their delamination, ...) before anything is computed. The high-level tables
(``[shaft]``, ``[[delamination]]``, ``[[obstacle]]``) are translated into the
low-level :class:`~nsfem.stack.BeamStack`; a scene may also give the low-level
``[[segment]]``, ``[[junction]]``, ``[[support]]`` and ``[[contact]]`` tables directly.

>>> scene = load_scene(None, ["delamination.0.friction=0.3", "mesh.elements=20"])
>>> scene["delamination"][0]["friction"], scene["mesh"]["elements"]
(0.3, 20)
>>> [s.name for s in scene.stack.segments]
['intact_0', 'delamination_0_upper', 'delamination_0_lower', 'intact_1']
>>> len(scene.stack.contacts)
9
"""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from .errors import SceneError
from .stack import (NORMALS, SECTIONS, SUPPORT_DOFS, THEORIES, WEIGHTINGS, BeamStack, Bearing, Contact, Disk, Junction,
                    Segment, Support, Unbalance)

SUPPORTS = ("pinned-pinned", "clamped-free", "clamped-clamped", "clamped-pinned", "free-free")
#: Dofs fixed at (x = 0, x = L) for each support name. Pinned-pinned fixes U at x = 0 only.
SUPPORT_DOFS_BY_NAME = {
    "pinned-pinned": (("U", "V", "W"), ("V", "W")),
    "clamped-free": (SUPPORT_DOFS, ()),
    "clamped-clamped": (SUPPORT_DOFS, SUPPORT_DOFS),
    "clamped-pinned": (SUPPORT_DOFS, ("V", "W")),
    "free-free": ((), ()),
}
REDUCTIONS = ("none", "modal", "craig-bampton")
METHODS = ("exact", "rk", "penalty", "moreau")
RK_SOLVERS = ("DOP853", "RK45")
STIFF_SOLVERS = ("BDF", "Radau", "LSODA")
PLOTS = ("phase", "gap", "psd", "forces", "campbell")
FRAMES = ("rotating", "inertial")
INITIAL_STATES = ("rest", "stationary")
AXIAL = ("P1", "P2")
#: Thinnest sub-beam, as a fraction of the shaft's height (bending stiffness ~ thickness^3).
MIN_LAYER = 1e-3
#: Closest two required mesh nodes (segment ends, contacts) may be, relative to the mean
#: element length: a very short element next to normal ones ruins the conditioning
#: (measured: contact points 1e-4 m apart at 40 elements shift an untouched frequency by 7e-5).
MIN_SPACING = 0.05
#: Element counts above this are refused: Hermite round-off grows like h^-4 and makes the
#: frequencies meaningless (measured: 0.4 % error at 10000 elements, garbage at 30000).
MAX_ELEMENTS = 5000
#: Upper bound on contact points per delamination (a guard against typos like 1e9).
MAX_CONTACT_POINTS = 100_000
#: Most generators r of a polygonal friction cone. The inscribed r-gon approximates the
#: circular cone to 1 - cos(pi / r) (r = 4: 29 %, 16: 1.9 %, 64: 0.12 %): at 64 the error is far
#: below the uncertainty of any measured friction coefficient, while each generator adds an LCP
#: unknown per frictional contact (the dense LCP grows like (m (r + 2))^2).
MAX_FRICTION_DIRECTIONS = 64
#: Bytes per squared LCP unknown of the dense pivoting (the matrix, the basis inverse and its
#: LU refactorization, 8 bytes each): the largest contact LCP must fit in the machine's memory.
LCP_BYTES_PER_ENTRY = 3 * 8
#: Deepest nesting of tables and lists a scene needs (an array of tables holding a list) plus margin.
MAX_NESTING = 8
#: E and rho must lie within these decades of 1 (in any consistent units). The finite-element
#: matrices carry E and rho as factors and the eigen solvers square their entries: the shipped
#: shaft's frequencies follow sqrt(E / rho) to 1e-8 for E and rho scaled by 1e-130 to 1e130, and
#: are lost (underflow, ARPACK failure) near 1e+-160. Every unit system in use (SI, mm-t-s with
#: rho ~ 1e-9, a nondimensional E = rho = 1) lies far inside.
MATERIAL_RANGE = (1e-100, 1e100)
#: Scene keys that hold file paths (relative to the scene file; ``--set`` ones to the cwd).
PATH_KEYS = ("mesh.file",)


# --------------------------------------------------------------------------- schema
@dataclass(frozen=True)
class Key:
    """One scene key: its kind, default, documentation and an optional value check."""

    kind: str  # float | int | str | bool | floats | strs | points | float?
    default: Any
    doc: str
    choices: tuple = ()
    check: Callable[[Any], str | None] | None = None
    length: int | None = None  # for lists of fixed length


def _positive(v):
    return None if v > 0 else f"must be positive, got {v}"


def _nonneg(v):
    return None if v >= 0 else f"must be >= 0, got {v}"


def _unit(v):
    return None if 0.0 <= v <= 1.0 else f"must lie in [0, 1], got {v}"


def _tolerance(v):
    return None if 0.0 < v < 1.0 else f"must lie in (0, 1), got {v}"


def _theta(v):
    return None if 0.5 <= v <= 1.0 else f"must lie in [0.5, 1], got {v}"


def _friction_directions(v):
    if v < 2 or v % 2:
        return f"must be an even integer >= 2, got {v}"
    if v > MAX_FRICTION_DIRECTIONS:
        return (f"{v} exceeds {MAX_FRICTION_DIRECTIONS}: the polygonal cone with r generators misses the circular "
                f"one by 1 - cos(pi/r) ({1 - math.cos(math.pi / MAX_FRICTION_DIRECTIONS):.1e} at r = "
                f"{MAX_FRICTION_DIRECTIONS}), and each generator adds an LCP unknown per frictional contact")
    return None


def _material(v):
    lo, hi = MATERIAL_RANGE
    if not v > 0:
        return f"must be positive, got {v}"
    if not lo <= v <= hi:
        return (f"{v:g} lies outside [{lo:g}, {hi:g}], where the eigen solvers' squares of the stiffness and mass "
                "entries leave double precision; choose units closer to 1 (E = rho = 1 nondimensionalizes)")
    return None


def _at_least(n):
    return lambda v: None if v >= n else f"must be >= {n}, got {v}"


def _all_nonneg(v):
    return None if all(x >= 0 for x in v) else f"entries must be >= 0, got {v}"


_SECTION = {
    "section": Key("str", "rectangle", "cross-section: rectangle (width, height) or circle (diameter, "
                   "inner_diameter)", SECTIONS),
    "width": Key("float", 0.02, "rectangle: section width b along y [m]", check=_positive),
    "height": Key("float", 0.02, "rectangle: section height h along z [m]", check=_positive),
    "diameter": Key("float", 0.02, "circle: outer diameter D [m]", check=_positive),
    "inner_diameter": Key("float", 0.0, "circle: bore d [m] (0 = solid)", check=_nonneg),
}
_SHAFT = {
    "length": Key("float", 1.0, "shaft length [m]", check=_positive),
    **_SECTION,
    "E": Key("float", 2.1e11, "Young's modulus [Pa] (the paper gives none; steel assumed; 1e-100 to 1e100)",
             check=_material),
    "rho": Key("float", 7500.0, "density [kg/m^3] (1e-100 to 1e100)", check=_material),
    "supports": Key("str", "pinned-pinned", "end conditions; pinned-pinned fixes U at x = 0 only", SUPPORTS),
}
_DELAMINATION = {
    "start": Key("float", 0.1, "x where the delamination starts [m]"),
    "end": Key("float", 0.9, "x where it ends [m]"),
    "upper_height": Key("float", 0.011, "thickness of the sub-beam above the interface [m]"),
    "contact_points": Key("points", 9, "count evenly spaced strictly inside (start, end), or a list of x [m]"),
    "weighting": Key("str", "dirac", "contact force ansatz: Dirac points or hat-weighted gaps (eq. 19)", WEIGHTINGS),
    "friction": Key("float", 0.0, "Coulomb coefficient mu (0 leaves friction out)", check=_nonneg),
    "friction_directions": Key("int", 4, "generators r of the polygonal friction cone (even, 2 to 64)",
                                  check=_friction_directions),
    "restitution": Key("float", 0.0, "Newton restitution eps in [0, 1]", check=_unit),
}
_OBSTACLE = {
    "x": Key("float?", None, "position of the stop along the shaft [m] (default: the shaft's end)"),
    "normal": Key("str", "+z", "direction n in the rotating frame; the stop is hit when n.u reaches the clearance",
                  NORMALS),
    "clearance": Key("float", 0.0, "initial gap [m]", check=_nonneg),
    "friction": Key("float", 0.0, "Coulomb coefficient mu", check=_nonneg),
    "friction_directions": Key("int", 4, "generators of the friction cone (even, 2 to 64)",
                                  check=_friction_directions),
    "restitution": Key("float", 0.0, "Newton restitution eps in [0, 1]", check=_unit),
}
_SEGMENT = {
    "name": Key("str", "", "unique name (default segment_<index>); mesh files name cell sets by it"),
    "start": Key("float", 0.0, "x of the left end [m]"),
    "end": Key("float", 1.0, "x of the right end [m]"),
    **_SECTION,
    "offset": Key("floats", [0.0, 0.0], "centroid offset (y_c, z_c) from the rotation axis [m]", length=2),
    "E": Key("float", 2.1e11, "Young's modulus [Pa] (1e-100 to 1e100)", check=_material),
    "rho": Key("float", 7500.0, "density [kg/m^3] (1e-100 to 1e100)", check=_material),
}
_JUNCTION = {
    "x": Key("float", 0.0, "position [m]; an end of the master and of every slave"),
    "master": Key("str", "", "name of the carrying segment"),
    "slaves": Key("strs", [], "names of the segments whose ends it carries"),
}
_SUPPORT = {
    "segment": Key("str", "", "segment name"),
    "x": Key("float", 0.0, "an end of that segment [m]"),
    "fix": Key("strs", ["V", "W"], "dofs held at zero", SUPPORT_DOFS),
}
_CONTACT = {
    "kind": Key("str", "interface", "interface (two faces) or obstacle (rigid stop)", ("interface", "obstacle")),
    "x": Key("float", 0.0, "position [m]"),
    "segments": Key("strs", [], "interface: [upper, lower]; obstacle: [segment]"),
    "weighting": Key("str", "dirac", "dirac | hat", WEIGHTINGS),
    "extent": Key("floats", [], "hat support [a, b] (only for weighting = hat)"),
    "normal": Key("str", "+z", "obstacle normal", NORMALS),
    "clearance": Key("float", 0.0, "obstacle initial gap [m]", check=_nonneg),
    "friction": Key("float", 0.0, "Coulomb mu", check=_nonneg),
    "friction_directions": Key("int", 4, "friction cone generators (even, 2 to 64)",
                                  check=_friction_directions),
    "restitution": Key("float", 0.0, "Newton eps", check=_unit),
}

_DISK = {
    "x": Key("float?", None, "position on the shaft [m] (default: the rotor's middle)"),
    "mass": Key("float?", None, "mass [kg]; or leave it out and give outer_diameter and width"),
    "polar_inertia": Key("float?", None, "polar moment of inertia I_p about the axis [kg m^2] (with mass; "
                         "default 0)"),
    "diametral_inertia": Key("float?", None, "diametral moment of inertia I_d [kg m^2] (with mass; default 0)"),
    "outer_diameter": Key("float?", None, "geometry instead of mass: outer diameter [m]"),
    "inner_diameter": Key("float", 0.0, "geometry: bore [m]", check=_nonneg),
    "width": Key("float?", None, "geometry: axial width [m]"),
    "rho": Key("float", 7850.0, "geometry: density [kg/m^3]", check=_material),
}
_BEARING = {
    "x": Key("float", 0.0, "position on the shaft [m]"),
    **{f"k{a}{b}": Key("float", 0.0, f"stiffness, force along {a} per displacement along {b} [N/m]")
       for a, b in ("yy", "zz", "yz", "zy")},
    **{f"c{a}{b}": Key("float", 0.0, f"damping, force along {a} per velocity along {b} [N s/m]")
       for a, b in ("yy", "zz", "yz", "zy")},
    "kxx": Key("float", 0.0, "axial stiffness on U [N/m] (a thrust bearing; 0 = none)", check=_nonneg),
}
_UNBALANCE = {
    "x": Key("float?", None, "position on the shaft [m] (default: the rotor's middle)"),
    "magnitude": Key("float", 0.0, "mass times eccentricity [kg m]", check=_nonneg),
    "phase_deg": Key("float", 0.0, "angle in the rotating frame from +y towards +z [deg]"),
}

_STATOR = {
    "x": Key("float?", None, "position on the shaft [m] (default: the rotor's middle)"),
    "clearance": Key("float", 1e-4, "radial gap at rest between the shaft surface and the ring [m]",
                     check=_positive),
    "facets": Key("int", 32, "sides of the polygon tangent to the clearance circle (3 to 1024; it misses "
                  "the circle by 1 - cos(pi / facets) of the clearance)",
                  check=lambda v: None if 3 <= v <= 1024 else f"must lie in [3, 1024], got {v}"),
    "stiffness": Key("float", 0.0, "0: rigid ring (Signorini, impacts with `restitution`); > 0: an elastic ring, "
                     "its radial mount stiffness [N/m]: the force is stiffness (r - clearance) + damping r' while "
                     "it pushes (a unilateral spring-damper, no impacts)", check=_nonneg),
    "damping": Key("float", 0.0, "radial damping of an elastic ring's mount [N s/m] (the force is released when "
                   "it would pull)", check=_nonneg),
    "friction": Key("float", 0.0, "Coulomb mu against the shaft surface, which slides past the ring at Omega "
                    "radius besides its whirl (circumferential friction; the axial slip is frictionless)",
                    check=_nonneg),
    "restitution": Key("float", 0.0, "Newton restitution eps in [0, 1]", check=_unit),
    "radius": Key("float", 0.0, "radius [m] of the surface the ring touches, for its speed Omega radius (0: "
                  "half the section's depth, a rectangle's height; a ring around a disk's rim: the rim's radius)",
                  check=_nonneg),
}
_SENSOR = {
    "name": Key("str", "", "column name in sensors.csv (default sensor_<index>)"),
    "x": Key("float", 0.0, "position on the shaft [m]"),
    "direction": Key("str", "+z", "displacement component read", ("+y", "+z", "-y", "-z")),
    "frame": Key("str", "inertial", "frame the displacement is measured in (a probe on the casing: inertial)",
                 FRAMES),
    "layer": Key("str", "", "inside a delamination: upper | lower", ("", "upper", "lower")),
}

#: The scene schema: tables of keys; a one-element list marks an array of tables.
SCHEMA: dict[str, Any] = {
    "title": Key("str", "nsfem scene", "free text shown in outputs"),
    "shaft": _SHAFT,
    "delamination": [_DELAMINATION],
    "obstacle": [_OBSTACLE],
    "beam": {
        "theory": Key("str", "euler-bernoulli", "euler-bernoulli, or rayleigh (adds rotary inertia)", THEORIES),
    },
    "rotation": {
        "speed_hz": Key("float", 0.0, "rotation speed [Hz] (0 = not rotating)", check=_nonneg),
        "gravity": Key("float", 9.81, "gravitational acceleration along inertial -Z [m/s^2] (0 = none)",
                       check=_nonneg),
        "phase_deg": Key("float", 0.0, "angle of the rotating frame at t = 0 [deg]"),
        "frame": Key("str", "rotating", "frame of the coordinates: rotating with the shaft (any rotor, isotropic "
                     "bearings) or inertial (axisymmetric rotors, any bearings)", FRAMES),
    },
    "damping": {
        "rayleigh": Key("floats", [0.0, 0.0], "internal Rayleigh damping [alpha 1/s, beta s]", length=2,
                        check=_all_nonneg),
        "external": Key("float", 0.0, "external viscous damping per unit length [N s/m^2]", check=_nonneg),
    },
    "mesh": {
        "elements": Key("int", 40, "number of elements over the length (nodes also at segment ends and contacts)",
                        check=lambda v: None if 1 <= v <= MAX_ELEMENTS else
                        f"must lie in [1, {MAX_ELEMENTS}] (Hermite round-off grows like h^-4), got {v}"),
        "file": Key("str", "", "meshio line mesh with one named cell set per segment (relative to the scene)"),
        "axial": Key("str", "P1", "Lagrange element of the axial field U", AXIAL),
    },
    "reduction": {
        "method": Key("str", "craig-bampton", "none | modal | craig-bampton", REDUCTIONS),
        "modes": Key("int", 16, "number of (fixed-interface) normal modes kept", check=_positive),
    },
    "initial": {
        "state": Key("str", "rest", "rest | stationary", INITIAL_STATES),
        "velocity": Key("floats", [0.0, 0.0, 0.0], "uniform initial velocity (u1, u2, u3) [m/s]", length=3),
    },
    "simulation": {
        "method": Key("str", "exact", "exact | rk | penalty | moreau", METHODS),
        "t_end": Key("float", 1.0, "simulated time [s]", check=_positive),
        "output_dt": Key("float", 1e-3, "output sampling step [s] (at most t_end)", check=_positive),
        "rk_solver": Key("str", "DOP853", "solve_ivp method of rk between events: DOP853 | RK45", RK_SOLVERS),
        "rtol": Key("float", 1e-8, "relative tolerance of rk and penalty", check=_tolerance),
        "atol": Key("float", 1e-12, "absolute tolerance of rk and penalty (reduced coordinates, about m and m/s)",
                    check=_positive),
        "penalty_stiffness": Key("float", 0.0, "penalty contact stiffness c_p [N/m]; 0 = penalty_factor times the "
                                 "largest static stiffness of the structure at a contact", check=_nonneg),
        "penalty_factor": Key("float", 100.0, "c_p as a multiple of the structure's contact stiffness (when "
                              "penalty_stiffness = 0)", check=_positive),
        "stiff_solver": Key("str", "BDF", "solve_ivp method of penalty: BDF | Radau | LSODA", STIFF_SOLVERS),
        "moreau_step": Key("float", 0.0, "time step of moreau [s]; 0 = output_dt / 10", check=_nonneg),
        "moreau_theta": Key("float", 0.5, "theta of moreau's theta-method, in [0.5, 1]", check=_theta),
    },
    "output": {
        "dir": Key("str", "out", "output directory (relative to the working directory)"),
        "vtu_every": Key("int", 10, "write a VTU every N output steps (0 = none)", check=_nonneg),
        "plots": Key("strs", ["phase", "gap", "psd", "forces"], "PNG plots to write", PLOTS),
    },
    "disk": [_DISK],
    "bearing": [_BEARING],
    "unbalance": [_UNBALANCE],
    "stator": [_STATOR],
    "sensor": [_SENSOR],
    "segment": [_SEGMENT],
    "junction": [_JUNCTION],
    "support": [_SUPPORT],
    "contact": [_CONTACT],
}
HIGH_LEVEL = ("shaft", "delamination", "obstacle")
LOW_LEVEL = ("segment", "junction", "support", "contact")


def defaults() -> dict:
    """The scene with every key at its default (high-level form, no delamination, no obstacle)."""
    out: dict = {}
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out[name] = copy.deepcopy(spec.default)
        elif isinstance(spec, dict):
            out[name] = {k: copy.deepcopy(v.default) for k, v in spec.items()}
    return out


def _check_value(key: str, spec: Key, value: Any) -> Any:
    """Type-check one value (with conversion int -> float) and run its range check."""

    def number(v, k):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise SceneError(k, f"must be a number, got {v!r}")
        if not math.isfinite(v):
            raise SceneError(k, f"must be finite, got {v}")
        return float(v)

    kind = spec.kind
    if kind == "float?" and value is None:
        return None
    if kind in ("float", "float?"):
        value = number(value, key)
    elif kind == "int":
        if isinstance(value, float) and not math.isfinite(value):
            raise SceneError(key, f"must be finite, got {value}")
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(key, f"must be an integer, got {value!r}")
    elif kind == "str":
        if not isinstance(value, str):
            raise SceneError(key, f"must be a string, got {value!r}")
        if spec.choices and value not in spec.choices:
            raise SceneError(key, f"unknown value {value!r} (use {' | '.join(spec.choices)})")
    elif kind == "bool":
        if not isinstance(value, bool):
            raise SceneError(key, f"must be true or false, got {value!r}")
    elif kind == "floats":
        if not isinstance(value, list):
            raise SceneError(key, f"must be a list of numbers, got {value!r}")
        value = [number(v, f"{key}.{i}") for i, v in enumerate(value)]
        if spec.length is not None and len(value) != spec.length:
            raise SceneError(key, f"must have {spec.length} entries, got {len(value)}")
    elif kind == "strs":
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise SceneError(key, f"must be a list of strings, got {value!r}")
        for v in value:
            if spec.choices and v not in spec.choices:
                raise SceneError(key, f"unknown entry {v!r} (use {', '.join(spec.choices)})")
    elif kind == "points":
        if isinstance(value, int) and not isinstance(value, bool):
            if value < 1:
                raise SceneError(key, f"must be >= 1, got {value}")
        elif isinstance(value, list):
            value = [number(v, f"{key}.{i}") for i, v in enumerate(value)]
            if not value:
                raise SceneError(key, "the list of contact points is empty")
        else:
            raise SceneError(key, f"must be a count or a list of x positions, got {value!r}")
    if spec.check is not None and value is not None:
        msg = spec.check(value)
        if msg:
            raise SceneError(key, msg)
    return value


def _check_table(prefix: str, spec: dict, raw: Any) -> dict:
    if not isinstance(raw, dict):
        raise SceneError(prefix, f"must be a table, got {raw!r}")
    for k in raw:
        if k not in spec:
            raise SceneError(f"{prefix}.{k}", f"unknown key (known: {', '.join(spec)})")
    return {k: _check_value(f"{prefix}.{k}", s, raw[k]) if k in raw else copy.deepcopy(s.default)
            for k, s in spec.items()}


def validate_tree(raw: dict) -> dict:
    """Check a raw scene tree against :data:`SCHEMA` and fill in defaults (no cross checks)."""
    if not isinstance(raw, dict):
        raise SceneError("", "a scene must be a TOML table")
    for k in raw:
        if k not in SCHEMA:
            raise SceneError(k, f"unknown key (known tables: {', '.join(SCHEMA)})")
    out: dict = {}
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out[name] = _check_value(name, spec, raw[name]) if name in raw else copy.deepcopy(spec.default)
        elif isinstance(spec, dict):
            out[name] = _check_table(name, spec, raw.get(name, {}))
        else:
            items = raw.get(name, [])
            if isinstance(items, dict):
                items = [items]
            if not isinstance(items, list):
                raise SceneError(name, f"must be an array of tables ([[{name}]]), got {items!r}")
            out[name] = [_check_table(f"{name}.{i}", spec[0], item) for i, item in enumerate(items)]
    return out


# --------------------------------------------------------------------------- overrides
def parse_value(text: str) -> Any:
    """A ``--set`` value: a TOML value (number, "string", [list], true), else the bare string.

    >>> parse_value("[0.0, 1e-5]"), parse_value('"stationary"'), parse_value("stationary"), parse_value("18")
    ([0.0, 1e-05], 'stationary', 'stationary', 18)
    """
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:  # a value nested deeper than the parser's recursion limit
        raise SceneError("", f"the value is nested too deeply to parse (a scene needs at most {MAX_NESTING} "
                         "levels of tables and lists)") from None


def nesting_depth(value: Any) -> int:
    """Levels of tables and lists in ``value`` (0 for a number or string), without recursion.

    >>> nesting_depth(1), nesting_depth([1, [2]]), nesting_depth({"a": [{"b": 1}]}), nesting_depth([[]])
    (0, 2, 3, 2)
    """
    depth, level = 0, [value]
    while level := [node for node in level if isinstance(node, (dict, list))]:
        depth += 1
        level = [v for node in level for v in (node.values() if isinstance(node, dict) else node)]
    return depth


def _check_nesting(value: Any, key: str, what: str) -> None:
    d = nesting_depth(value)
    if d > MAX_NESTING:
        raise SceneError(key, f"{what} is nested {d} levels deep; a scene needs at most {MAX_NESTING} levels of "
                         "tables and lists")


def apply_override(tree: dict, assignment: str, cwd: Path | None = None) -> None:
    """Apply one ``KEY=VALUE`` to a raw scene tree in place (dotted keys, list items by index)."""
    if "=" not in assignment:
        raise SceneError(assignment, "an override must look like KEY=VALUE")
    key, text = assignment.split("=", 1)
    key = key.strip()
    parts = key.split(".")
    if not key or any(p == "" for p in parts):
        raise SceneError(key or assignment, "empty key in override")
    try:
        value = parse_value(text.strip())
    except SceneError as exc:
        raise SceneError(key, exc.reason) from None
    _check_nesting(value, key, "the value")
    if key in PATH_KEYS and isinstance(value, str) and value:
        value = str((cwd or Path.cwd()) / value)
    node: Any = tree
    for i, part in enumerate(parts[:-1]):
        nxt_is_index = _is_index(parts[i + 1])
        node = _step(node, part, key, create=[] if nxt_is_index else {})
    last = parts[-1]
    if isinstance(node, list):
        idx = _index(node, last, key)
        if idx == len(node):
            node.append(value)
        else:
            node[idx] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise SceneError(key, f"{'.'.join(parts[:-1])} is not a table")


def _is_index(part: str) -> bool:
    return part.isascii() and part.isdigit()


def _index(node: list, part: str, key: str) -> int:
    if not _is_index(part):
        raise SceneError(key, f"{part!r} must be a list index")
    idx = int(part)
    if idx > len(node):
        raise SceneError(key, f"index {idx} is past the end of a list of {len(node)}")
    return idx


def _step(node: Any, part: str, key: str, create: Any) -> Any:
    if isinstance(node, list):
        idx = _index(node, part, key)
        if idx == len(node):
            node.append({})
        return node[idx]
    if isinstance(node, dict):
        if _is_index(part):
            raise SceneError(key, f"{part} indexes a table, not a list")
        if part not in node:
            # a known array of tables ([[delamination]]) is created as a list
            node[part] = [] if isinstance(SCHEMA.get(part), list) and node is not None else create
        return node[part]
    raise SceneError(key, f"cannot descend into {part!r}")


# --------------------------------------------------------------------------- scene
class Scene(dict):
    """A validated scene: the full key tree (with defaults) plus its low-level BeamStack.

    ``scene.path`` is the file it came from (None for the shipped default), ``scene.base``
    the directory relative paths in it refer to.
    """

    def __init__(self, tree: dict, stack: BeamStack, path: Path | None, base: Path, sensors: tuple = ()):
        super().__init__(tree)
        self.stack = stack
        self.path = path
        self.base = base
        self.sensors = sensors

    @property
    def mesh_file(self) -> Path | None:
        f = self["mesh"]["file"]
        return (self.base / f) if f else None

    def record(self) -> dict:
        """The validated tree as a results file stores it: ``mesh.file`` resolved to the absolute
        path this scene read (a relative one means nothing to a later ``export`` run from another
        folder), and its SHA-256 under ``mesh.sha256`` so that a changed mesh is noticed."""
        tree = copy.deepcopy(dict(self))
        if self.mesh_file is not None:
            import hashlib

            path = self.mesh_file.resolve()
            tree["mesh"]["file"] = str(path)
            tree["mesh"]["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
        return tree


def default_scene_path() -> Path:
    """Path of the scene shipped with the package (the paper's delaminated shaft)."""
    return Path(str(resources.files("nsfem.scenes").joinpath("default.toml")))


def shipped_scenes() -> dict[str, Path]:
    """The scenes shipped in the package, by name (``nsfem run ross_example``)."""
    root = resources.files("nsfem.scenes")
    return {Path(str(f)).stem: Path(str(f)) for f in root.iterdir() if str(f).endswith(".toml")}


def scene_file(path: str | Path | None) -> Path:
    """The file a SCENE argument names: the path itself, or a shipped scene's file when the path is no
    file but a shipped scene's name (``None``: the default scene)."""
    p = Path(path) if path is not None else default_scene_path()
    if not p.is_file() and path is not None and str(path) in shipped_scenes():
        p = shipped_scenes()[str(path)]
    return p


def load_scene(path: str | Path | None = None, overrides: Iterable[str] = (),
               cwd: Path | None = None) -> Scene:
    """Read, override and validate a scene; ``path=None`` is the shipped default scene, and a name
    that is no file but a shipped scene's (:func:`shipped_scenes`) is that scene."""
    p = scene_file(path)
    if not p.exists():
        raise SceneError("scene", f"file not found: {p} (shipped scenes: {', '.join(sorted(shipped_scenes()))})")
    if not p.is_file():
        raise SceneError("scene", f"not a file: {p}")
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("scene", f"{p.name} is not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise SceneError("scene", f"{p.name} is not a UTF-8 text file") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise SceneError("scene", f"{p.name} is nested too deeply to parse (a scene needs at most "
                         f"{MAX_NESTING} levels of tables and lists)") from None
    _check_nesting(raw, "scene", p.name)
    return scene_from_tree(raw, overrides, path=p if path is not None else None, base=p.parent, cwd=cwd)


def scene_from_tree(raw: dict, overrides: Iterable[str] = (), path: Path | None = None,
                    base: Path | None = None, cwd: Path | None = None) -> Scene:
    """Validate a raw scene tree (e.g. from ``tomllib``) after applying ``overrides``."""
    raw = copy.deepcopy(raw)
    for o in overrides:
        apply_override(raw, o, cwd)
    tree = validate_tree(raw)
    sim = tree["simulation"]
    if sim["output_dt"] > sim["t_end"]:
        raise SceneError("simulation.output_dt", f"{sim['output_dt']} s exceeds t_end = {sim['t_end']} s")
    if sim["moreau_step"] > sim["output_dt"]:
        raise SceneError("simulation.moreau_step", f"{sim['moreau_step']} s exceeds output_dt = {sim['output_dt']} s")
    if sim["t_end"] / sim["output_dt"] > 1e7:
        raise SceneError("simulation.output_dt", f"t_end / output_dt = {sim['t_end'] / sim['output_dt']:.3g} "
                         "output steps exceeds the limit of 1e7")
    _check_section_keys(raw)
    if any(t in raw for t in LOW_LEVEL):
        mixed = [t for t in HIGH_LEVEL if t in raw]
        if mixed:
            raise SceneError(mixed[0], "the low-level form ([[segment]] ...) cannot be mixed with "
                             "[shaft], [[delamination]] or [[obstacle]]")
        stack = low_level_stack(tree)
    else:
        stack = high_level_stack(tree)
    base = base or Path.cwd()
    stack = point_components(tree, stack).validate()
    check_scales(tree, stack)
    check_components(tree, stack)
    check_frame(tree, stack)
    check_speed(tree["rotation"]["speed_hz"], stack)
    if not tree["mesh"]["file"]:
        from .mesh import breakpoints

        bp = breakpoints(stack)
        need = len(bp) - 1
        if need > tree["mesh"]["elements"]:
            raise SceneError("mesh.elements", f"{tree['mesh']['elements']} is fewer than the {need} intervals "
                             "between segment ends and contact points; use at least that many")
        gaps = np.diff(bp)
        h = (bp[-1] - bp[0]) / tree["mesh"]["elements"]
        k = int(np.argmin(gaps))
        if gaps[k] < MIN_SPACING * h:
            raise SceneError(_node_key(stack, bp[k], bp[k + 1]),
                             f"nodes at x={bp[k]:.12g} and x={bp[k + 1]:.12g} are {gaps[k]:.3g} m apart, less than "
                             f"{MIN_SPACING:g} of the element length {h:.3g} m; move them apart or refine the mesh")
    if tree["mesh"]["file"]:
        f = base / tree["mesh"]["file"]
        if not f.is_file():
            raise SceneError("mesh.file", f"file not found: {f}")
    from .sensors import sensors_from_scene

    return Scene(tree, stack, path, base, sensors_from_scene(tree, stack))


# --------------------------------------------------------------------------- speed bound
def speed_limit_hz(stack: BeamStack) -> tuple[float, Segment]:
    """The speed [Hz] at which a section's outermost fibre reaches the bar wave speed sqrt(E/rho),
    and the segment that sets it.

    The centrifugal stress of a fibre at radius r is about rho (Omega r)^2, its strain
    rho (Omega r)^2 / E = (Omega r / c)^2: at Omega = c / r the rotor would stretch by 100 %
    from spinning alone, beyond any elastic model (the shipped steel shaft: 59.6 kHz, 1200
    times its first critical speed).
    """
    def limit(s: Segment) -> float:
        if s.section == "circle":
            r = math.hypot(s.offset[0], s.offset[1]) + s.width / 2
        else:
            r = math.hypot(abs(s.offset[0]) + s.width / 2, abs(s.offset[1]) + s.height / 2)
        return math.sqrt(s.E / s.rho) / r / (2 * math.pi)

    seg = min(stack.segments, key=limit)
    return limit(seg), seg


def check_speed(speed_hz: float, stack: BeamStack, key: str = "rotation.speed_hz") -> None:
    """Refuse a rotation speed whose centrifugal strain (Omega r / c)^2 reaches 1 (:func:`speed_limit_hz`)."""
    if not stack.segments:
        return
    f_lim, seg = speed_limit_hz(stack)
    if not speed_hz < f_lim:
        strain = (speed_hz / f_lim) * (speed_hz / f_lim)  # inf, not OverflowError, past 1e154
        raise SceneError(key, f"{speed_hz:g} Hz spins the outermost fibre of {seg.name} faster than the bar wave "
                         f"speed sqrt(E/rho) = {math.sqrt(seg.E / seg.rho):.4g} m/s: centrifugal strain "
                         f"rho (Omega r)^2 / E = {strain:.3g} >= 1, beyond any elastic model (the limit is "
                         f"{f_lim:.4g} Hz)")


# --------------------------------------------------------------------------- scales
def _magnitude(v: float) -> float:
    """Orders of magnitude between v and 1 (infinite for 0)."""
    return abs(math.log10(v)) if v > 0 else math.inf


def check_scales(tree: dict, stack: BeamStack) -> None:
    """Refuse material and size combinations whose element matrices leave double precision.

    Per segment: the element mass rho A l, the stiffnesses E A / l and E I / l^3 (both planes) and the squared
    frequency scale (E A / l) / (rho A l) must lie in :data:`MATERIAL_RANGE` (l: the element
    length). Inside it the frequencies scale exactly as sqrt(E / rho) (tests/test_bounds.py).
    """
    lo, hi = MATERIAL_RANGE
    low = any(t in tree and tree[t] for t in LOW_LEVEL)
    span = max(s.end for s in stack.segments) - min(s.start for s in stack.segments)
    for i, s in enumerate(stack.segments):
        prefix = f"segment.{i}" if low else "shaft"
        le = span / tree["mesh"]["elements"] if not tree["mesh"]["file"] else s.length
        with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
            E, rho, b, h, le = (np.float64(v) for v in (s.E, s.rho, s.width, s.height, le))
            if s.section == "circle":
                area, I_y = np.pi / 4 * (b * b - s.inner**2), np.pi / 64 * (b**4 - np.float64(s.inner) ** 4)
                I_z = I_y
            else:
                area, I_y, I_z = b * h, b * h**3 / 12.0, h * b**3 / 12.0  # numpy: inf, not OverflowError
            mass, axial = rho * area * le, E * area / le
            bend_w, bend_v = E * I_y / le**3, E * I_z / le**3
            w2 = axial / mass if mass > 0 else np.inf
        # the key to blame: the input farthest from 1 in orders of magnitude among those involved
        span_key = "end" if low else "length"
        size = {"E": _magnitude(s.E), "rho": _magnitude(s.rho), span_key: _magnitude(float(le)),
                "width": _magnitude(s.width), "height": _magnitude(s.height)}
        for name, v, keys in (("element mass rho A l", mass, ("rho", span_key, "width", "height")),
                              ("axial stiffness E A / l", axial, ("E", span_key, "width", "height")),
                              ("bending stiffness E I_y / l^3", bend_w, ("E", span_key, "width", "height")),
                              ("bending stiffness E I_z / l^3", bend_v, ("E", span_key, "width", "height")),
                              ("squared frequency scale E / (rho l^2)", w2, ("E", "rho", span_key))):
            if not lo <= v <= hi:
                key = max(keys, key=size.get)
                raise SceneError(f"{prefix}.{key}", f"the {name} of {s.name} is {v:.3g}, outside [{lo:g}, {hi:g}] "
                                 "where the eigen solvers stay in double precision; choose units closer to 1 "
                                 "(E = rho = 1 nondimensionalizes)")


#: Disks and bearings may differ from the shaft element they sit on by at most this factor (mass, stiffness):
#: beyond it the eigen solvers lose the shaft next to them (a bearing 1e12 times stiffer than the shaft is
#: a support: ``supports`` holds it exactly)
COMPONENT_RANGE = 1e12


def check_components(tree: dict, stack: BeamStack) -> None:
    """Refuse disks and bearings whose mass or stiffness leaves double precision next to the shaft's."""
    span = max(s.end for s in stack.segments) - min(s.start for s in stack.segments)
    le = span / tree["mesh"]["elements"]
    mass = min(s.rho * s.area * le for s in stack.segments)
    stiff = max(max(s.E * s.area / le, s.E * max(s.I_y, s.I_z) / le**3) for s in stack.segments)
    for d in stack.disks:
        if d.mass > COMPONENT_RANGE * mass:
            given = tree["disk"][int(d.label.split(".")[1])]["mass"] is not None if d.label else True
            raise SceneError(f"{d.label}.{'mass' if given else 'outer_diameter'}", f"{d.mass:.3g} kg is more than {COMPONENT_RANGE:g} times a shaft "
                             f"element's mass ({mass:.3g} kg): double precision cannot hold both")
    for b in stack.bearings:
        for name, v in (("kyy", b.K[0][0]), ("kzz", b.K[1][1]), ("kyz", b.K[0][1]), ("kzy", b.K[1][0]),
                        ("kxx", b.kxx)):
            if abs(v) > COMPONENT_RANGE * stiff:
                raise SceneError(f"{b.label}.{name}", f"{v:.3g} N/m is more than {COMPONENT_RANGE:g} times the "
                                 f"shaft's stiffest element ({stiff:.3g} N/m): a rigid support is what it models "
                                 "(shaft.supports)")


# --------------------------------------------------------------------------- translation
def _node_key(stack: BeamStack, *xs: float) -> str:
    """The scene key of a contact at one of ``xs`` (else the mesh), for error messages."""
    for c in stack.contacts:
        if c.x in xs:
            return c.label.rsplit(".", 1)[0] + ".contact_points" if c.label.startswith("delamination") else c.label
    return "mesh.elements"


def contact_positions(d: dict) -> list[float]:
    """x positions of one delamination's contact points."""
    cp = d["contact_points"]
    if isinstance(cp, int):
        a, b = d["start"], d["end"]
        return [float(f"{a + (b - a) * (k + 1) / (cp + 1):.12g}") for k in range(cp)]
    return sorted(cp)


def _check_section_keys(raw: dict) -> None:
    """Refuse a section key the section does not use (a circle's width, a rectangle's diameter) set to
    anything but its default: it would be silently ignored (a results file's full tree holds every key
    at its default)."""
    tables = [("shaft", raw.get("shaft"))] + [(f"segment.{i}", t) for i, t in enumerate(raw.get("segment", []))
                                              if isinstance(raw.get("segment"), list)]
    for key, t in tables:
        if not isinstance(t, dict):
            continue
        circle = t.get("section", "rectangle") == "circle"
        unused = [k for k in (("width", "height") if circle else ("diameter", "inner_diameter"))
                  if k in t and t[k] != _SECTION[k].default]
        if unused:
            raise SceneError(f"{key}.{unused[0]}", f"a {'circular' if circle else 'rectangular'} section does not use "
                             f"{unused[0]} (circle: diameter, inner_diameter; rectangle: width, height)")


def section(table: dict, key: str) -> dict:
    """The Segment keywords of a table's section: width and height (a circle's diameter twice), section,
    inner (a circle's bore)."""
    if table["section"] == "circle":
        D, d = table["diameter"], table["inner_diameter"]
        if not d < D:
            raise SceneError(f"{key}.inner_diameter", f"must be smaller than diameter ({D}), got {d}")
        return dict(width=D, height=D, section="circle", inner=d)
    return dict(width=table["width"], height=table["height"])


def high_level_stack(tree: dict) -> BeamStack:
    """Translate ``[shaft]``, ``[[delamination]]``, ``[[obstacle]]`` into a BeamStack (checked first)."""
    sh = tree["shaft"]
    L = sh["length"]
    sec = section(sh, "shaft")
    b, h = sec["width"], sec["height"]
    mat = dict(E=sh["E"], rho=sh["rho"])
    if tree["delamination"] and sh["section"] != "rectangle":
        raise SceneError("delamination.0", "a delamination splits a rectangular section into two layers; "
                         "use shaft.section = \"rectangle\"")
    dels = sorted(enumerate(tree["delamination"]), key=lambda it: it[1]["start"])
    for i, d in dels:
        key = f"delamination.{i}"
        if not 0.0 <= d["start"] < d["end"] <= L:
            if d["start"] >= d["end"]:
                raise SceneError(f"{key}.end", f"must exceed start ({d['start']}), got {d['end']}")
            raise SceneError(key, f"[{d['start']}, {d['end']}] lies outside the shaft [0, {L}]")
        if not 0.0 < d["upper_height"] < h:
            raise SceneError(f"{key}.upper_height", f"must lie strictly between 0 and height ({h}), "
                             f"got {d['upper_height']}")
        if min(d["upper_height"], h - d["upper_height"]) < MIN_LAYER * h:
            raise SceneError(f"{key}.upper_height", f"leaves a sub-beam thinner than {MIN_LAYER:g} of the height "
                             f"({h}); its bending stiffness would be lost to round-off")
        cp = d["contact_points"]
        n_cp = cp if isinstance(cp, int) else len(cp)
        if not tree["mesh"]["file"] and n_cp >= tree["mesh"]["elements"]:
            raise SceneError("mesh.elements", f"{tree['mesh']['elements']} is fewer than the {n_cp + 1} "
                             f"intervals that the {n_cp} contact points of {key} need")
        if n_cp > MAX_CONTACT_POINTS:
            raise SceneError(f"{key}.contact_points", f"{n_cp} exceeds the limit of {MAX_CONTACT_POINTS}")
        xs = contact_positions(d)
        if isinstance(d["contact_points"], list):
            for x in xs:
                if not d["start"] < x < d["end"]:
                    raise SceneError(f"{key}.contact_points", f"x={x} lies outside the delamination "
                                     f"({d['start']}, {d['end']})")
            if len(set(xs)) != len(xs):
                dup = next(x for x in xs if xs.count(x) > 1)
                raise SceneError(f"{key}.contact_points", f"duplicate contact point x={dup}")
    for (i, a), (j, c) in zip(dels, dels[1:]):
        if c["start"] <= a["end"]:
            raise SceneError(f"delamination.{j}", f"overlaps or touches delamination {i} "
                             f"([{c['start']}, {c['end']}] vs [{a['start']}, {a['end']}])")

    segments: list[Segment] = []
    junctions: list[Junction] = []
    contacts: list[Contact] = []
    cursor, last = 0.0, None  # last: the intact segment that ends at cursor
    layers: dict[int, tuple[Segment, Segment]] = {}

    def intact(a: float, c: float) -> Segment:
        seg = Segment(f"intact_{sum(s.name.startswith('intact_') for s in segments)}", a, c, offset=(0.0, 0.0),
                      **sec, **mat)
        segments.append(seg)
        return seg

    for n, (i, d) in enumerate(dels):
        x0, x1 = d["start"], d["end"]
        if x0 > cursor:
            last = intact(cursor, x0)
        hu = d["upper_height"]
        hl = h - hu
        zi = (hl - hu) / 2.0  # interface height that keeps the intact centroid on the axis
        up = Segment(f"delamination_{i}_upper", x0, x1, b, hu, (0.0, zi + hu / 2), **mat)
        lo = Segment(f"delamination_{i}_lower", x0, x1, b, hl, (0.0, zi - hl / 2), **mat)
        segments += [up, lo]
        layers[i] = (up, lo)
        if last is not None and last.end == x0:
            junctions.append(Junction(x0, last.name, (up.name, lo.name)))
        xs = contact_positions(d)
        knots = [x0, *xs, x1]
        for k, x in enumerate(xs):
            contacts.append(Contact(
                "interface", x, (up.name, lo.name), d["weighting"],
                (knots[k], knots[k + 2]) if d["weighting"] == "hat" else None,
                friction=d["friction"], friction_directions=d["friction_directions"],
                restitution=d["restitution"], label=f"delamination.{i}.{k}"))
        cursor, last = x1, None
        if x1 < L:
            stop = dels[n + 1][1]["start"] if n + 1 < len(dels) else L
            last = intact(x1, stop)
            junctions.append(Junction(x1, last.name, (up.name, lo.name)))
            cursor = stop
    if cursor < L:
        intact(cursor, L)

    at0, atL = SUPPORT_DOFS_BY_NAME[sh["supports"]]
    supports = [Support(s.name, 0.0, at0) for s in segments if s.start == 0.0 and at0]
    supports += [Support(s.name, L, atL) for s in segments if s.end == L and atL]

    for i, o in enumerate(tree["obstacle"]):
        key = f"obstacle.{i}"
        x = L if o["x"] is None else o["x"]
        if not 0.0 <= x <= L:
            raise SceneError(f"{key}.x", f"x={x} lies outside the shaft [0, {L}]")
        whole = [s for s in segments if s.name.startswith("intact_") and s.start <= x <= s.end]
        if whole:
            seg = whole[0]
        else:
            j, (up, lo) = next((j, ud) for j, ud in layers.items() if ud[0].start <= x <= ud[0].end)
            if o["normal"] not in ("+z", "-z"):
                raise SceneError(f"{key}.normal", f"a stop with normal {o['normal']!r} at x={x} in delamination "
                                 f"{j} would touch both sub-beams; only +z (upper) or -z (lower) stops may act there")
            seg = up if o["normal"] == "+z" else lo
        contacts.append(Contact("obstacle", x, (seg.name,), "dirac", None, o["normal"], o["clearance"],
                                o["friction"], o["friction_directions"], o["restitution"], label=key))
    return BeamStack(tuple(segments), tuple(junctions), tuple(supports), tuple(contacts), tree["beam"]["theory"])


def low_level_stack(tree: dict) -> BeamStack:
    """Build a BeamStack from ``[[segment]]``, ``[[junction]]``, ``[[support]]``, ``[[contact]]``."""
    segs = tuple(Segment(s["name"] or f"segment_{i}", s["start"], s["end"], offset=tuple(s["offset"]), E=s["E"],
                         rho=s["rho"], **section(s, f"segment.{i}")) for i, s in enumerate(tree["segment"]))
    juns = tuple(Junction(j["x"], j["master"], tuple(j["slaves"])) for j in tree["junction"])
    sups = tuple(Support(s["segment"], s["x"], tuple(s["fix"])) for s in tree["support"])
    cons = []
    for i, c in enumerate(tree["contact"]):
        ext = c["extent"]
        if ext and len(ext) != 2:
            raise SceneError(f"contact.{i}.extent", f"must be [a, b], got {ext}")
        cons.append(Contact(c["kind"], c["x"], tuple(c["segments"]), c["weighting"], tuple(ext) if ext else None,
                            c["normal"], c["clearance"], c["friction"], c["friction_directions"],
                            c["restitution"], label=f"contact.{i}"))
    return BeamStack(segs, juns, sups, tuple(cons), tree["beam"]["theory"])


def disk_inertia(d: dict, key: str) -> tuple[float, float, float]:
    """(mass, polar, diametral) of a ``[[disk]]``: given, or from its geometry (a thick annulus:
    m = rho pi (D^2 - d^2) w / 4, I_p = m (D^2 + d^2) / 8, I_d = I_p / 2 + m w^2 / 12)."""
    geometry = d["outer_diameter"] is not None or d["width"] is not None
    if d["mass"] is not None:
        if geometry:
            raise SceneError(f"{key}.mass", "give either mass (and inertias) or the geometry (outer_diameter, width), "
                             "not both")
        m, ip, id_ = d["mass"], d["polar_inertia"] or 0.0, d["diametral_inertia"] or 0.0
        for name, v in (("mass", m), ("polar_inertia", ip), ("diametral_inertia", id_)):
            if not v >= 0.0:
                raise SceneError(f"{key}.{name}", f"must be >= 0, got {v}")
        if not m > 0.0:
            raise SceneError(f"{key}.mass", f"must be positive, got {m}")
        return m, ip, id_
    if d["polar_inertia"] is not None or d["diametral_inertia"] is not None:
        raise SceneError(f"{key}.mass", "inertias need a mass (or give the geometry alone)")
    if d["outer_diameter"] is None or d["width"] is None:
        raise SceneError(f"{key}.mass", "a disk needs a mass, or its outer_diameter and width")
    D, di, w = d["outer_diameter"], d["inner_diameter"], d["width"]
    if not (D > 0 and w > 0):
        raise SceneError(f"{key}.outer_diameter" if not D > 0 else f"{key}.width", "must be positive")
    if not di < D:
        raise SceneError(f"{key}.inner_diameter", f"must be smaller than outer_diameter ({D}), got {di}")
    m = d["rho"] * math.pi / 4.0 * (D * D - di * di) * w
    ip = m * (D * D + di * di) / 8.0
    return m, ip, ip / 2.0 + m * w * w / 12.0


def point_components(tree: dict, stack: BeamStack) -> BeamStack:
    """``stack`` with the scene's ``[[disk]]``, ``[[bearing]]`` and ``[[unbalance]]`` on it."""
    from dataclasses import replace

    lo, hi = min(s.start for s in stack.segments), max(s.end for s in stack.segments)
    middle = float(f"{(lo + hi) / 2:.12g}")
    disks = tuple(Disk(middle if d["x"] is None else d["x"], *disk_inertia(d, f"disk.{i}"), label=f"disk.{i}",
                       **({"outer_diameter": d["outer_diameter"], "inner_diameter": d["inner_diameter"],
                           "width": d["width"]} if d["mass"] is None else {}))
                  for i, d in enumerate(tree["disk"]))
    bearings = tuple(Bearing(b["x"], ((b["kyy"], b["kyz"]), (b["kzy"], b["kzz"])),
                             ((b["cyy"], b["cyz"]), (b["czy"], b["czz"])), b["kxx"], label=f"bearing.{i}")
                     for i, b in enumerate(tree["bearing"]))
    unbalances = tuple(Unbalance(middle if u["x"] is None else u["x"], u["magnitude"], math.radians(u["phase_deg"]),
                                 label=f"unbalance.{i}") for i, u in enumerate(tree["unbalance"]))
    return replace(stack, disks=disks, bearings=bearings, unbalances=unbalances,
                   contacts=stack.contacts + stator_contacts(tree, stack, middle))


def stator_contacts(tree: dict, stack: BeamStack, middle: float) -> tuple[Contact, ...]:
    """Each ``[[stator]]`` as ``facets`` stops at one x (rigid, or the facets of an elastic ring,
    :mod:`nsfem.contact.ring`): facet k's normal points at the angle
    2 pi k / facets in the y-z plane, its gap is clearance - n.(v, w) (the polygon tangent to the
    clearance circle; a ring fixed in the frame of the coordinates: in space in the inertial frame,
    an approximation of the same circle in the rotating one). Friction acts along the circumference
    against the shaft surface of radius ``radius`` sliding past (see
    :func:`~nsfem.contact.set.surface_velocity`)."""
    out = []
    for i, st in enumerate(tree["stator"]):
        key = f"stator.{i}"
        if st["damping"] > 0.0 and st["stiffness"] == 0.0:
            raise SceneError(f"{key}.damping", "damping belongs to an elastic ring's mount: give the ring a "
                             "stiffness > 0 (a rigid ring, stiffness = 0, takes restitution instead)")
        if st["stiffness"] > 0.0 and st["restitution"] > 0.0:
            raise SceneError(f"{key}.restitution", "an elastic ring (stiffness > 0) has no impacts, so no "
                             "restitution: set it to 0 (its damping sets the energy a rub loses)")
        x = middle if st["x"] is None else st["x"]
        seg = stack.carrier(x) if math.isfinite(x) else None
        if seg is None:
            lo, hi = min(g.start for g in stack.segments), max(g.end for g in stack.segments)
            raise SceneError(f"{key}.x", f"x={x} must lie on the intact shaft within [{lo}, {hi}]")
        held = [sp for sp in stack.supports if abs(sp.x - x) <= 1e-12 * max(1.0, abs(x)) and {"V", "W"} <= set(sp.fix)]
        if held:
            raise SceneError(f"{key}.x", f"x={x} is a support, which holds the shaft's centre there: the ring would "
                             "never be touched; put it where the shaft can move")
        n = st["facets"]
        radius = st["radius"] or stack.segment(seg).height / 2.0
        for k in range(n):
            angle = 2.0 * math.pi * k / n
            c, s_ = math.cos(angle), math.sin(angle)
            axis = ("+y" if c > 0 else "-y") if abs(c) >= abs(s_) else ("+z" if s_ > 0 else "-z")
            # friction along the circumference only (r = 2 on the first tangent, slip_rows' order)
            out.append(Contact("obstacle", x, (seg,), "dirac", None, axis, st["clearance"], st["friction"], 2,
                               st["restitution"], label=f"{key}.{k}", angle=angle, radius=radius,
                               stiffness=st["stiffness"], damping=st["damping"]))
    return tuple(out)


def check_frame(tree: dict, stack: BeamStack) -> None:
    """Refuse a scene whose equations have periodic coefficients in its frame (design section 8).

    Rotating frame: a bearing that is not isotropic turns with respect to the coordinates. Inertial
    frame: a rotor that is not axisymmetric (a delamination, a rectangular section, an offset centroid)
    turns with respect to them; and friction at a stop fixed in space acts against a surface that
    slides past it at Omega r, which a point stop does not model."""
    rot = tree["rotation"]
    check_frame_at_speed(rot["frame"], stack, rot["speed_hz"] > 0.0)
    if rot["frame"] == "inertial" and rot["speed_hz"] > 0.0:
        for c in stack.contacts:
            if c.friction > 0.0 and c.angle is None:   # (a stator's facet models the sliding surface)
                raise SceneError(f"{c.label}.friction", "friction at a stop fixed in space acts against the shaft "
                                 "surface sliding past it at Omega r, which a point stop does not model; set it to "
                                 "0 in the inertial frame")


def check_frame_at_speed(frame: str, stack: BeamStack, spinning: bool = True) -> None:
    """The frame check of :func:`check_frame` for a rotor that spins (``campbell`` and speed sweeps
    spin a scene given at rest)."""
    odd = next((s for s in stack.segments if not s.axisymmetric), None)
    if frame == "rotating":
        bad = next((i for i, b in enumerate(stack.bearings) if not b.isotropic), None)
        if spinning and bad is not None:
            b = stack.bearings[bad]
            why = (f"bearing.{bad} is not isotropic (K = {[list(r) for r in b.K]}, C = {[list(r) for r in b.C]}): in "
                   "the rotating frame its force has periodic coefficients")
            if odd is None:
                raise SceneError("rotation.frame", f"{why}; this rotor is axisymmetric, so use rotation.frame = "
                                 "\"inertial\"")
            raise SceneError("rotation.frame", f"{why}, and segment {odd.name!r} is not axisymmetric, so the "
                             "inertial frame cannot carry it either: the equations have periodic coefficients in "
                             "both frames (no closed-form propagation)")
        return
    if odd is not None:
        what = ("its centroid sits off the axis" if odd.offset != (0.0, 0.0) else
                f"its section is {odd.width:g} x {odd.height:g}, not square or round")
        raise SceneError("rotation.frame", f"the inertial frame needs an axisymmetric rotor, but segment {odd.name!r} "
                         f"is not ({what}): its stiffness would turn with the shaft; use rotation.frame = "
                         "\"rotating\"")


# --------------------------------------------------------------------------- reference
def _fmt(v: Any) -> str:
    if v is None:
        return "(see text)"
    if isinstance(v, str):
        return f'`"{v}"`' if v else '`""`'
    if isinstance(v, bool):
        return f"`{str(v).lower()}`"
    return f"`{v}`"


def scene_reference() -> str:
    """Markdown reference of every scene key with its default (``docs/scene.md``)."""
    out = ["# Scene reference", "",
           "Generated from `nsfem.scene.SCHEMA` by `python -m nsfem.scene > docs/scene.md`; a test keeps it",
           "current. Units are SI. Keys left out take the default shown; unknown keys are errors.",
           "A scene uses either the high-level tables (`[shaft]`, `[[delamination]]`, `[[obstacle]]`)",
           "or the low-level ones (`[[segment]]`, `[[junction]]`, `[[support]]`, `[[contact]]`); the",
           "other tables apply to both. Override any key from the command line with",
           "`--set table.key=VALUE` (list items by index: `--set delamination.0.friction=0.3`; an index",
           "one past the end appends an item).", ""]
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out += [f"## `{name}`", "", f"{spec.doc}. Default {_fmt(spec.default)}.", ""]
            continue
        table, array = (spec[0], True) if isinstance(spec, list) else (spec, False)
        out += [f"## `[[{name}]]` (zero or more)" if array else f"## `[{name}]`", "",
                "| key | default | meaning |", "|---|---|---|"]
        for k, s in table.items():
            doc = s.doc + (f"; one of {', '.join(f'`{c}`' for c in s.choices)}" if s.choices else "")
            out.append(f"| `{k}` | {_fmt(s.default)} | {doc} |")
        out.append("")
    out += ["## Supports", "", "| supports | fixed at x = 0 | fixed at x = L |", "|---|---|---|"]
    for k, (a, b) in SUPPORT_DOFS_BY_NAME.items():
        out.append(f"| `{k}` | {', '.join(a) or 'none'} | {', '.join(b) or 'none'} |")
    out += ["", "A prime marks a slope (V' = dV/dx). Where a delamination reaches a shaft end, the support",
            "holds each sub-beam.", ""]
    return "\n".join(out)


if __name__ == "__main__":  # pragma: no cover
    print(scene_reference())
