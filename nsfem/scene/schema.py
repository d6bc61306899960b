"""The scene schema: every table's keys (:class:`Key`: kind, default, documentation, value check)
and the limits the checks use."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from ..stack import CRACK_SIDES, NORMALS, SECTIONS, SHEAR_COEFFICIENTS, SUPPORT_DOFS, THEORIES, WEIGHTINGS


#: The axes, said wherever a key could be read in another program's axes (ROSS's x is horizontal).
AXES = ("x is the shaft axis: kxx is an axial (thrust) stiffness; the lateral directions are y (horizontal) and z "
        "(vertical, up)")
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


@dataclass(frozen=True)
class Key:
    """One scene key: its kind, default, documentation and an optional value check."""

    kind: str  # float | int | str | bool | floats | strs | points | float? | coef (a number or a list)
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


#: Smallest relative tolerance of rk and penalty: scipy's explicit solvers raise anything below 100 machine
#: epsilons (2.2e-14) to it, where the error estimate is round-off itself (penalty's BDF needs 1e-13)
RTOL_FLOOR = 100 * 2.0 ** -52
#: penalty_factor's range. c_p = factor k, k the stiffest contact point's static stiffness: the structure and
#: the penalty spring in series let 1 / (1 + factor) of the contact-free deflection through the contact, so
#: below 1 most of it passes (no contact at all: an elastic stator's stiffness models a soft ring); above
#: 1e12 the penalty spring outweighs the shaft's stiffest element as a bearing may not (checks.COMPONENT_RANGE)
PENALTY_FACTOR_RANGE = (1.0, 1e12)


def _rtol(v):
    if not v < 1.0:
        return f"must be below 1, got {v}"
    if not v >= RTOL_FLOOR:
        return (f"{v:g} is below {RTOL_FLOOR:.3g} = 100 machine epsilons, where the solvers' error estimates are "
                "round-off (scipy would raise it silently)")
    return None


def _penalty_factor(v):
    lo, hi = PENALTY_FACTOR_RANGE
    if not lo <= v <= hi:
        return (f"{v:g} lies outside [{lo:g}, {hi:g}]: the penalty spring in series with the structure lets "
                f"1 / (1 + factor) of the contact-free deflection through the contact (below {lo:g}, most of it: no "
                f"contact; an elastic stator's stiffness models a soft ring), and above {hi:g} it outweighs the "
                "shaft's stiffest element beyond double precision")
    return None


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
                   "inner_diameter); left out, a table that gives diameter or inner_diameter and neither width "
                   "nor height is a circle", SECTIONS),
    "width": Key("float", 0.02, "rectangle: section width b along y [m]", check=_positive),
    "height": Key("float", 0.02, "rectangle: section height h along z [m]", check=_positive),
    "diameter": Key("float", 0.02, "circle: outer diameter D [m]", check=_positive),
    "inner_diameter": Key("float", 0.0, "circle: bore d [m] (0 = solid)", check=_nonneg),
}
_STEP = {
    "start": Key("float", 0.0, "x where the step starts [m] (inside [0, length]; steps may touch, not overlap)"),
    "end": Key("float", 0.0, "x where it ends [m] (above start)"),
    "diameter": Key("float?", None, "circle: outer diameter D [m] (left out: the shaft's)", check=_positive),
    "inner_diameter": Key("float?", None, "circle: bore d [m] (left out: the shaft's)", check=_nonneg),
    "width": Key("float?", None, "rectangle: width b along y [m] (left out: the shaft's)", check=_positive),
    "height": Key("float?", None, "rectangle: height h along z [m] (left out: the shaft's)", check=_positive),
    "E": Key("float?", None, "Young's modulus [Pa] (left out: the shaft's)", check=_material),
    "rho": Key("float?", None, "density [kg/m^3] (left out: the shaft's)", check=_material),
    "G": Key("float?", None, "shear modulus [Pa] (left out: the shaft's if the step keeps its E, else "
             "E / (2 (1 + 0.3)))", check=_material),
}
_SHAFT = {
    "length": Key("float", 1.0, "shaft length [m]", check=_positive),
    **_SECTION,
    "E": Key("float", 2.1e11, "Young's modulus [Pa] (the paper gives none; steel assumed; 1e-100 to 1e100)",
             check=_material),
    "rho": Key("float", 7850.0, "density [kg/m^3] (steel; the paper's shaft states 7500; 1e-100 to 1e100)",
               check=_material),
    "G": Key("float?", None, "shear modulus [Pa] for theory = \"timoshenko\" (left out: E / (2 (1 + 0.3)); "
             "E / (2 G) - 1 must lie in [0, 0.5])", check=_material),
    "supports": Key("str", "pinned-pinned", "end conditions; pinned-pinned fixes U at x = 0 only. A rotor scene "
                    "(one with [[bearing]]) has none unless it says so: its default is free-free, the bearings "
                    "hold it", SUPPORTS),
    "step": [_STEP],
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
    "rho": Key("float", 7850.0, "density [kg/m^3] (steel; 1e-100 to 1e100)", check=_material),
    "G": Key("float?", None, "shear modulus [Pa] for theory = \"timoshenko\" (left out: E / (2 (1 + 0.3)))",
             check=_material),
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
                         "default 0: no gyroscopic moment, said in a note)"),
    "diametral_inertia": Key("float?", None, "diametral moment of inertia I_d [kg m^2] (with mass; default 0: no "
                             "rotary inertia, said in a note)"),
    "outer_diameter": Key("float?", None, "geometry instead of mass: outer diameter [m]"),
    "inner_diameter": Key("float", 0.0, "geometry: bore [m]", check=_nonneg),
    "width": Key("float?", None, "geometry: axial width [m]"),
    "rho": Key("float", 7850.0, "geometry: density [kg/m^3]", check=_material),
}
def _coefficient_nonneg(v):
    vals = v if isinstance(v, list) else [v]
    return None if all(x >= 0 for x in vals) else f"must be >= 0, got {v}"


def _speeds_table(v):
    if not v:
        return None
    if len(v) < 2:
        return f"a table needs at least two speeds, got {v}"
    if v[0] < 0:
        return f"speeds must be >= 0, got {v[0]}"
    if any(b <= a for a, b in zip(v, v[1:])):
        return f"speeds must increase strictly, got {v}"
    return None


_TABLE = " (a number, or with speeds_hz a list of one value per speed)"
_BEARING = {
    "x": Key("float", 0.0, "position on the shaft [m]"),
    "speeds_hz": Key("floats", [], "speed-dependent coefficients: the rotation speeds [Hz] of a table (strictly "
                     "increasing, at least two); each coefficient given as a list holds one value per speed and is "
                     "interpolated linearly in speed; a speed outside the table is refused ([] = constant "
                     "coefficients)", check=_speeds_table),
    **{f"k{a}{b}": Key("coef", 0.0, f"stiffness, force along {a} per displacement along {b} [N/m]{_TABLE}")
       for a, b in ("yy", "zz", "yz", "zy")},
    **{f"c{a}{b}": Key("coef", 0.0, f"damping, force along {a} per velocity along {b} [N s/m]{_TABLE}")
       for a, b in ("yy", "zz", "yz", "zy")},
    "kxx": Key("coef", 0.0, "axial stiffness on U [N/m]: x is the shaft axis, so this is a thrust bearing (0 = "
               "none); with lateral keys, a note when kzz is missing or kxx is as large as kyy or kzz: write a "
               f"thrust bearing as its own [[bearing]] with kxx alone{_TABLE}", check=_coefficient_nonneg),
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
    "shape": Key("str", "polygon", "a rigid ring in the exact method: polygon (the `facets` fixed) or round (the "
                 "polygon turns with the contact point so that the touched facet stays tangent to the circle and a "
                 "settled point is held, docs/theory.md); rk, moreau, penalty and elastic rings use the polygon; "
                 "`nsfem periodic` refuses round (its turns keep a state besides (q, q'))",
                 ("polygon", "round")),
}
_CRACK = {
    "x": Key("float?", None, "position on the intact shaft [m] (default: the rotor's middle); it splits the shaft "
             "there into two sides joined by a hinge"),
    "depth": Key("float", 0.3, "relative depth a/h (rectangle, h the section's size along side; up to 0.8) or a/D "
                 "(solid circle; up to 0.5); any depth above 0: a crack too shallow to hold in double precision is "
                 "a hinge 1e4 times stiffer than a shaft element, the intact shaft to 1e-4 of an element's flexibility",
                 check=lambda v: None if 0.0 < v <= 0.8 else
                 f"must lie in (0, 0.8] (the stress-intensity fits of the open crack's compliance end there), got {v}"),
    "side": Key("str", "-z", "the section face the crack starts from, in the rotating frame (-z: the bottom at "
                "phase 0, in tension under gravity at rest)", CRACK_SIDES),
    "friction": Key("float", 0.0, "between the crack faces: must be 0 (the hinge shares the faces' "
                    "displacements, so they cannot slide)", check=lambda v: None if v == 0.0 else
                    f"must be 0: the crack's hinge shares the faces' displacements, so they cannot slide and face "
                    f"friction would have no effect, got {v}"),
    "restitution": Key("float", 0.0, "Newton restitution eps in [0, 1] of the faces' impacts at closure",
                       check=_unit),
}
_SENSOR = {
    "name": Key("str", "", "column name in sensors.csv (default sensor_<index>; no comma, quote, control character or blank at either end)"),
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
        "theory": Key("str", "euler-bernoulli", "euler-bernoulli, rayleigh (adds the shaft's rotary inertia and "
                      "gyroscopic moments) or timoshenko (rayleigh and shear deformation, ROSS's default; the "
                      "second dof of a node is then the section's rotation); a rotor left at the default gets a "
                      "note", THEORIES),
        "shear_coefficient": Key("str", "cowper", "timoshenko: a circle's shear coefficient, cowper (ROSS's "
                                 "default) or hutchinson (2001); rectangles use Cowper's 10 (1 + nu) / (12 + 11 nu)",
                                 SHEAR_COEFFICIENTS),
    },
    "rotation": {
        "speed_hz": Key("float", 0.0, "rotation speed [Hz] (0 = not rotating)", check=_nonneg),
        "gravity": Key("float", 9.81, "gravitational acceleration along inertial -Z [m/s^2] (0 = none)",
                       check=_nonneg),
        "phase_deg": Key("float", 0.0, "angle of the rotating frame at t = 0 [deg]"),
        "frame": Key("str", "rotating", "frame of the coordinates: rotating with the shaft (any rotor, isotropic "
                     "bearings) or inertial (axisymmetric rotors, any bearings)", FRAMES),
        "ramp_to_hz": Key("float?", None, "run-up or coast-down: the speed [Hz] reached linearly from speed_hz "
                          "over ramp_s, kept after (methods rk, penalty, moreau)", check=_nonneg),
        "ramp_s": Key("float", 0.0, "duration of the ramp to ramp_to_hz [s] (> 0 with ramp_to_hz)",
                      check=_nonneg),
        "speed_table_s": Key("floats", [], "instead of a ramp, a piecewise-linear speed: its times [s] (from 0, "
                             "increasing; the last speed kept after)"),
        "speed_table_hz": Key("floats", [], "the table's speeds [Hz] (>= 0; the first is speed_hz)"),
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
        "rtol": Key("float", 1e-8, "relative tolerance of rk and penalty (2.2e-14 to 1; penalty: from 1e-13)",
                     check=_rtol),
        "atol": Key("float", 1e-12, "absolute tolerance of rk and penalty (reduced coordinates, about m and m/s)",
                    check=_positive),
        "penalty_stiffness": Key("float", 0.0, "penalty contact stiffness c_p [N/m]; 0 = penalty_factor times the "
                                 "largest static stiffness of the structure at a contact", check=_nonneg),
        "penalty_factor": Key("float", 100.0, "c_p as a multiple of the structure's contact stiffness (when "
                              "penalty_stiffness = 0; 1 to 1e12)", check=_penalty_factor),
        "stiff_solver": Key("str", "BDF", "solve_ivp method of penalty: BDF | Radau | LSODA", STIFF_SOLVERS),
        "moreau_step": Key("float", 0.0, "time step of moreau [s]; 0 = output_dt / 10", check=_nonneg),
        "moreau_theta": Key("float", 0.5, "theta of moreau's theta-method, in [0.5, 1]", check=_theta),
    },
    "output": {
        "dir": Key("str", "out", "output directory (relative to the working directory)"),
        "vtu_every": Key("int", 10, "write a VTU frame every N output steps into the output folder's vtu/, "
                          "indexed by its nsfem.pvd (0 = none)", check=_nonneg),
        "plots": Key("strs", ["phase", "gap", "psd", "forces"],
                     "PNG plots to write (campbell: over `nsfem campbell`'s default speeds; left out, a scene without "
                     "contacts gets no gap or forces)", PLOTS),
    },
    "disk": [_DISK],
    "bearing": [_BEARING],
    "unbalance": [_UNBALANCE],
    "stator": [_STATOR],
    "crack": [_CRACK],
    "sensor": [_SENSOR],
    "segment": [_SEGMENT],
    "junction": [_JUNCTION],
    "support": [_SUPPORT],
    "contact": [_CONTACT],
}
HIGH_LEVEL = ("shaft", "delamination", "obstacle")
LOW_LEVEL = ("segment", "junction", "support", "contact")
