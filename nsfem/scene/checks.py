"""Cross-checks of a translated scene: rotation speed, number scales, components, frame."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..stack import BeamStack, Segment
from .schema import LOW_LEVEL, MATERIAL_RANGE, MIN_SPACING
from .translate import _node_key


# --------------------------------------------------------------------------- times
def check_times(sim: dict) -> None:
    """Refuse a ``[simulation]`` whose output step exceeds t_end, whose moreau step exceeds the output
    step, or that has more than 1e7 output steps."""
    if sim["output_dt"] > sim["t_end"]:
        raise SceneError("simulation.output_dt", f"{sim['output_dt']} s exceeds t_end = {sim['t_end']} s")
    if sim["moreau_step"] > sim["output_dt"]:
        raise SceneError("simulation.moreau_step", f"{sim['moreau_step']} s exceeds output_dt = {sim['output_dt']} s")
    if sim["t_end"] / sim["output_dt"] > 1e7:
        raise SceneError("simulation.output_dt", f"t_end / output_dt = {sim['t_end'] / sim['output_dt']:.3g} "
                         "output steps exceeds the limit of 1e7")


# --------------------------------------------------------------------------- mesh
def check_mesh(mesh: dict, stack: BeamStack, base: Path) -> None:
    """Refuse a generated mesh with fewer elements than the intervals between required nodes (segment
    ends, contact points) or two such nodes closer than :data:`MIN_SPACING` of the element length;
    a mesh file that ``base / mesh.file`` does not name."""
    if not mesh["file"]:
        from ..mesh import breakpoints

        bp = breakpoints(stack)
        need = len(bp) - 1
        if need > mesh["elements"]:
            raise SceneError("mesh.elements", f"{mesh['elements']} is fewer than the {need} intervals "
                             "between segment ends and contact points; use at least that many")
        gaps = np.diff(bp)
        h = (bp[-1] - bp[0]) / mesh["elements"]
        k = int(np.argmin(gaps))
        if gaps[k] < MIN_SPACING * h:
            raise SceneError(_node_key(stack, bp[k], bp[k + 1]),
                             f"nodes at x={bp[k]:.12g} and x={bp[k + 1]:.12g} are {gaps[k]:.3g} m apart, less than "
                             f"{MIN_SPACING:g} of the element length {h:.3g} m; move them apart or refine the mesh")
    if mesh["file"]:
        f = base / mesh["file"]
        if not f.is_file():
            raise SceneError("mesh.file", f"file not found: {f}")


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
        size = {"E": _magnitude(s.E), "rho": _magnitude(s.rho), span_key: _magnitude(float(le))}
        # a circle's section size is its diameter (held in width and height)
        cut = ("diameter",) if s.section == "circle" else ("width", "height")
        size.update({"diameter": _magnitude(s.width)} if s.section == "circle" else
                    {"width": _magnitude(s.width), "height": _magnitude(s.height)})
        table = prefix
        if not low and tree["shaft"]["step"]:   # a stepped shaft's piece: the step that gives the key, else [shaft]
            step = next((j for j, st in enumerate(tree["shaft"]["step"])
                         if (st["start"], st["end"]) == (s.start, s.end)), None)
            table = None if step is None else f"shaft.step.{step}"
        for name, v, keys in (("element mass rho A l", mass, ("rho", span_key, *cut)),
                              ("axial stiffness E A / l", axial, ("E", span_key, *cut)),
                              ("bending stiffness E I_y / l^3", bend_w, ("E", span_key, *cut)),
                              ("bending stiffness E I_z / l^3", bend_v, ("E", span_key, *cut)),
                              ("squared frequency scale E / (rho l^2)", w2, ("E", "rho", span_key))):
            if not lo <= v <= hi:
                key = max(keys, key=size.get)
                if table != prefix and table is not None and tree["shaft"]["step"][step].get(key) is not None:
                    prefix = table
                raise SceneError(f"{prefix}.{key}", f"the {name} of {s.name} is {v:.3g}, outside [{lo:g}, {hi:g}] "
                                 "where the eigen solvers stay in double precision; choose units closer to 1 "
                                 "(E = rho = 1 nondimensionalizes)")


#: Disks and bearings may differ from the shaft element they sit on by at most this factor (mass, stiffness):
#: beyond it the eigen solvers lose the shaft next to them (a bearing 1e12 times stiffer than the shaft is
#: a support: ``supports`` holds it exactly)
COMPONENT_RANGE = 1e12


#: A stator's surface radius may be at most this many rotor lengths (:func:`check_components`)
MAX_RADIUS = 1e3


def check_components(tree: dict, stack: BeamStack) -> None:
    """Refuse disks, bearings, unbalances and stators whose mass, stiffness, damping or size leaves double
    precision next to the shaft's: a mass or stiffness more than :data:`COMPONENT_RANGE` times a shaft element's;
    a damping c whose ratio c / (2 sqrt(k m)) on the stiffest element k with the lightest one's mass m exceeds
    ``nsfem.system.ZETA_MAX`` = 1 / (2 sqrt(eps)), the bound of ``damping.rayleigh`` (the slow and fast decay
    rates of so overdamped a mode differ by 4 zeta^2, more than double precision holds)."""
    span = max(s.end for s in stack.segments) - min(s.start for s in stack.segments)
    le = span / tree["mesh"]["elements"]
    mass = min(s.rho * s.area * le for s in stack.segments)
    stiff = max(max(s.E * s.area / le, s.E * max(s.I_y, s.I_z) / le**3) for s in stack.segments)
    for d in stack.disks:
        for name, v in (("polar_inertia", d.polar), ("diametral_inertia", d.diametral)):
            if v > COMPONENT_RANGE * mass * le * le:
                given = tree["disk"][int(d.label.split(".")[1])]["mass"] is not None if d.label else True
                what = name.replace("_", " ")
                raise SceneError(f"{d.label}.{name if given else 'outer_diameter'}", f"the disk's {what} "
                                 f"{v:.3g} kg m^2 is more than {COMPONENT_RANGE:g} times a shaft element's rotary "
                                 f"scale m l^2 ({mass * le * le:.3g} kg m^2): double precision cannot hold both")
        if d.mass > COMPONENT_RANGE * mass:
            given = tree["disk"][int(d.label.split(".")[1])]["mass"] is not None if d.label else True
            raise SceneError(f"{d.label}.{'mass' if given else 'outer_diameter'}", f"{d.mass:.3g} kg is more than {COMPONENT_RANGE:g} times a shaft "
                             f"element's mass ({mass:.3g} kg): double precision cannot hold both")
    for u in stack.unbalances:
        if u.magnitude > COMPONENT_RANGE * mass * span:
            raise SceneError(f"{u.label}.magnitude", f"{u.magnitude:.3g} kg m is more than {COMPONENT_RANGE:g} times a "
                             f"shaft element's mass times the rotor's length ({mass * span:.3g} kg m): its load leaves "
                             "double precision beside the shaft's own inertia")
    for b in stack.bearings:
        for name, v in (("kyy", b.K[0][0]), ("kzz", b.K[1][1]), ("kyz", b.K[0][1]), ("kzy", b.K[1][0]),
                        ("kxx", b.kxx)):
            if abs(v) > COMPONENT_RANGE * stiff:
                raise SceneError(f"{b.label}.{name}", f"{v:.3g} N/m is more than {COMPONENT_RANGE:g} times the "
                                 f"shaft's stiffest element ({stiff:.3g} N/m): a rigid support is what it models "
                                 "(shaft.supports)")
    from ..system import ZETA_MAX

    critical = math.sqrt(stiff * mass)
    c_max = 2.0 * ZETA_MAX * critical
    for b in stack.bearings:
        for name, v in (("cyy", b.C[0][0]), ("czz", b.C[1][1]), ("cyz", b.C[0][1]), ("czy", b.C[1][0])):
            if abs(v) > c_max:
                raise SceneError(f"{b.label}.{name}", _overdamped(v, critical))
    for c in stack.contacts:
        if c.radius > MAX_RADIUS * span:
            raise SceneError(f"{c.table_key}.radius", f"{c.radius:g} m is more than {MAX_RADIUS:g} times the rotor's "
                             f"length ({span:g} m): the radius arms the slopes in the friction's slip rows, where it "
                             "would dwarf every other entry (no rim is that large)")
        if c.stiffness > COMPONENT_RANGE * stiff:
            raise SceneError(f"{c.table_key}.stiffness", f"{c.stiffness:.3g} N/m is more than {COMPONENT_RANGE:g} "
                             f"times the shaft's stiffest element ({stiff:.3g} N/m): a rigid ring (stiffness = 0) "
                             "is what it models")
        if c.damping > c_max:
            raise SceneError(f"{c.table_key}.damping", _overdamped(c.damping, critical))


def _overdamped(c: float, critical: float) -> str:
    from ..system import ZETA_MAX

    return (f"{c:.3g} N s/m gives the shaft's stiffest element, on its lightest mass, a damping ratio c / (2 sqrt(k m)) "
            f"= {c / (2.0 * critical):.3g}, beyond {ZETA_MAX:.2g}: its slow and fast decay rates differ by 4 zeta^2, "
            "more than double precision can hold")


# --------------------------------------------------------------------------- frame
def check_frame(tree: dict, stack: BeamStack) -> None:
    """Refuse a scene whose equations have periodic coefficients in its frame (design section 8).

    Rotating frame: a bearing that is not isotropic turns with respect to the coordinates. Inertial
    frame: a rotor that is not axisymmetric (a delamination, a rectangular section, an offset centroid)
    turns with respect to them; and friction at a stop fixed in space acts against a surface that
    slides past it at Omega r, which a point stop does not model."""
    rot = tree["rotation"]
    # a run-up from rest spins too
    spinning = max(rot["speed_hz"], rot.get("ramp_to_hz") or 0.0, *(rot.get("speed_table_hz") or [0.0])) > 0.0
    check_frame_at_speed(rot["frame"], stack, spinning)
    if rot["frame"] == "inertial" and spinning:
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
            rows = [(v, replace(b.at_speed(v), table=())) for v in b.table[0]] if b.table else [(None, b)]
            v, row = next((v, r) for v, r in rows if not r.isotropic)   # a table: its first anisotropic row
            at = "" if v is None else f" at {v:g} Hz of its table"
            why = (f"bearing.{bad} is not isotropic{at} (K = {[list(r) for r in row.K]}, "
                   f"C = {[list(r) for r in row.C]}): in the rotating frame its force has periodic coefficients")
            if odd is None and stack.cracks:
                raise SceneError("rotation.frame", f"{why}, and {stack.cracks[0].label} turns with the shaft, so the "
                                 "inertial frame cannot carry it either: the equations have periodic coefficients in "
                                 "both frames (no closed-form propagation)")
            if odd is None:
                raise SceneError("rotation.frame", f"{why}; this rotor is axisymmetric, so use rotation.frame = "
                                 "\"inertial\"")
            raise SceneError("rotation.frame", f"{why}, and segment {odd.name!r} is not axisymmetric, so the "
                             "inertial frame cannot carry it either: the equations have periodic coefficients in "
                             "both frames (no closed-form propagation)")
        return
    if stack.cracks:
        raise SceneError("rotation.frame", f"the inertial frame needs an axisymmetric rotor, but {stack.cracks[0].label} "
                         "turns with the shaft (its hinge is stiffer in one direction than in the other): use "
                         "rotation.frame = \"rotating\" (sensors can still read in the inertial frame)")
    if odd is not None:
        what = ("its centroid sits off the axis" if odd.offset != (0.0, 0.0) else
                f"its section is {odd.width:g} x {odd.height:g}, not square or round")
        raise SceneError("rotation.frame", f"the inertial frame needs an axisymmetric rotor, but segment {odd.name!r} "
                         f"is not ({what}): its stiffness would turn with the shaft; use rotation.frame = "
                         "\"rotating\"")
