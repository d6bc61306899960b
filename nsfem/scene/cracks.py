"""Translation of ``[[crack]]``: each crack splits the segment that carries it into two sides joined by a
hinge (:class:`~nsfem.stack.Crack`) and adds the crack faces' contact points (kind ``"crack"``)."""

from __future__ import annotations

import math
from dataclasses import replace

from ..errors import SceneError
from ..fem.crack import MAX_CIRCLE_DEPTH, face_points, hinge_compliance, slope_compliance
from ..stack import BeamStack, Contact, Crack, Junction, Segment, Support


def _split(stack: BeamStack, seg: Segment, x: float, right_name: str) -> BeamStack:
    """``stack`` with ``seg`` cut at x: the left part keeps the name, what referred to its right end or to
    points beyond x refers to the right part."""
    left, right = replace(seg, end=x), replace(seg, name=right_name, start=x)
    segments = tuple(p for s in stack.segments for p in ((left, right) if s.name == seg.name else (s,)))
    moved = lambda name, at: right_name if name == seg.name and at > x else name  # noqa: E731
    supports = tuple(Support(moved(s.segment, s.x), s.x, s.fix) for s in stack.supports)
    junctions = tuple(Junction(j.x, moved(j.master, j.x), tuple(moved(n, j.x) for n in j.slaves))
                      for j in stack.junctions)
    contacts = tuple(replace(c, segments=tuple(moved(n, c.x) for n in c.segments)) for c in stack.contacts)
    # (cracks are cut in the order of x: an earlier crack lies left of x and keeps its names)
    return replace(stack, segments=segments, supports=supports, junctions=junctions, contacts=contacts)


def crack_stack(tree: dict, stack: BeamStack, mesh_file: bool = False) -> BeamStack:
    """``stack`` with the scene's ``[[crack]]`` entries: the carrying segment is split at x (the left part
    keeps its name, the right one is ``<name>_crack_<i>``), the sides are joined by a hinge with the open
    crack's compliance (:func:`nsfem.fem.crack.slope_compliance`) and the crack faces' vertices become
    contacts ``crack.<i>.<k>`` (:func:`nsfem.fem.crack.face_points`)."""
    if not tree["crack"]:
        return stack
    lo, hi = min(s.start for s in stack.segments), max(s.end for s in stack.segments)
    middle = float(f"{(lo + hi) / 2:.12g}")
    at = [middle if cr["x"] is None else cr["x"] for cr in tree["crack"]]
    order = sorted(range(len(at)), key=lambda i: at[i] if math.isfinite(at[i]) else math.inf)
    seen: dict[float, int] = {}
    elements = tree["mesh"]["elements"]
    for i in order:
        cr = tree["crack"][i]
        key = f"crack.{i}"
        x = middle if cr["x"] is None else cr["x"]
        if mesh_file:
            raise SceneError(f"{key}.x", "a crack splits the shaft into two segments, which a mesh file does not "
                             "name: leave mesh.file empty (the mesh is generated with a node at the crack)")
        if x in seen:
            raise SceneError(f"{key}.x", f"x={x} already holds crack.{seen[x]}")
        seen[x] = i
        if not (math.isfinite(x) and lo < x < hi):
            raise SceneError(f"{key}.x", f"x={x} must lie inside the rotor ({lo}, {hi})")
        inside = [s for s in stack.segments if s.start < x < s.end]
        ends = [s for s in stack.segments if x in (s.start, s.end)]
        if ends and not inside:
            raise SceneError(f"{key}.x", f"x={x} is where segments meet (a junction or a segment end): move the crack "
                             "into a segment")
        if len(inside) != 1:
            raise SceneError(f"{key}.x", f"x={x} lies where two layers of a delamination run side by side; a crack "
                             "cuts the intact shaft")
        seg = inside[0]
        if any(c.kind == "interface" and seg.name in c.segments for c in stack.contacts):
            raise SceneError(f"{key}.x", f"segment {seg.name!r} is a delamination's layer; a crack cuts the intact shaft")
        if seg.section == "circle" and cr["depth"] > MAX_CIRCLE_DEPTH:
            raise SceneError(f"{key}.depth", f"must be at most {MAX_CIRCLE_DEPTH} in a circular section, got "
                             f"{cr['depth']}: deeper, the crack cuts through the strips at its front's ends and the "
                             "strip integration of its compliance has no meaning")
        if seg.section == "circle" and seg.inner > 0.0:
            raise SceneError(f"{key}.depth", "the open crack's compliance is known for solid sections only (a hollow "
                             "shaft's strips cross the bore): use inner_diameter = 0")
        if seg.offset != (0.0, 0.0):
            raise SceneError(f"{key}.x", f"segment {seg.name!r} has its centroid off the axis; a crack cuts a shaft "
                             "whose centroid is on the axis")
        right = f"{seg.name}_crack_{i}"
        stack = _split(stack, seg, x, right)
        compliance = hinge_compliance(slope_compliance(seg.section, seg.E, seg.width, seg.height, cr["depth"],
                                                       cr["side"]), seg.E, seg.I_z, seg.I_y, (hi - lo) / elements)
        crack = Crack(x, (seg.name, right), cr["depth"], cr["side"], compliance, label=key)
        faces = tuple(Contact("crack", x, (seg.name, right), restitution=cr["restitution"], label=f"{key}.{k}",
                              arm=(float(y), float(z)), normal=cr["side"])
                      for k, (y, z) in enumerate(face_points(seg.section, seg.width, seg.height, cr["depth"],
                                                             cr["side"])))
        stack = replace(stack, cracks=stack.cracks + (crack,), contacts=stack.contacts + faces)
    return stack
