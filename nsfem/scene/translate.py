"""Translation of the scene's tables into a low-level :class:`~nsfem.stack.BeamStack`: the high-level
shaft with its delaminations and obstacles, the low-level segments, and the point components and stators."""

from __future__ import annotations

import math

from ..errors import SceneError
from ..stack import BeamStack, Bearing, Contact, Disk, Junction, Segment, Support, Unbalance
from .schema import _SECTION, MAX_CONTACT_POINTS, MIN_LAYER, SUPPORT_DOFS_BY_NAME
from .validate import section_of


def _node_key(stack: BeamStack, *xs: float) -> str:
    """The scene key of a contact or a point component (disk, bearing, unbalance) at one of ``xs`` (else the
    mesh), for error messages; one away from the segments' ends first (an end cannot be moved)."""
    ends = {x for s in stack.segments for x in (s.start, s.end)}
    for inner in (True, False):
        for c in stack.contacts:
            if c.x in xs and (c.x not in ends or not inner):
                if c.label.startswith("delamination"):
                    return c.table_key + ".contact_points"
                return c.table_key + ".x" if c.table_key else "mesh.elements"
        for p in stack.points():
            if p.x in xs and p.label and (p.x not in ends or not inner):
                return p.label + ".x"
    for s in stack.segments:   # a delamination's end (its layers are named delamination_<i>_upper)
        parts = s.name.split("_")
        if len(parts) == 3 and parts[0] == "delamination" and parts[2] == "upper":
            for x, end in ((s.start, "start"), (s.end, "end")):
                if x in xs and x not in (min(ends), max(ends)):
                    return f"delamination.{parts[1]}.{end}"
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
        circle = section_of(t) == "circle"
        unused = [k for k in (("width", "height") if circle else ("diameter", "inner_diameter"))
                  if k in t and t[k] != _SECTION[k].default]
        if unused:
            said = "" if "section" in t else (" (no section given: width or height says rectangle; a round shaft "
                                              "is section = \"circle\" with diameter alone)")
            raise SceneError(f"{key}.{unused[0]}", f"a {'circular' if circle else 'rectangular'} section does not use "
                             f"{unused[0]} (circle: diameter, inner_diameter; rectangle: width, height){said}")


def section(table: dict, key: str) -> dict:
    """The Segment keywords of a table's section: width and height (a circle's diameter twice), section,
    inner (a circle's bore)."""
    if table["section"] == "circle":
        D, d = table["diameter"], table["inner_diameter"]
        if not d < D:
            raise SceneError(f"{key}.inner_diameter", f"must be smaller than diameter ({D}), got {d}")
        return dict(width=D, height=D, section="circle", inner=d)
    return dict(width=table["width"], height=table["height"])


def shaft_steps(sh: dict) -> list[tuple[float, float, dict, dict]]:
    """The pieces of constant section of ``[shaft]`` with its ``[[shaft.step]]``: (start, end, section keywords,
    material) from x = 0 to the length, a step's section replacing the shaft's where it lies (checked: steps inside
    the shaft, not overlapping, of the shaft's section kind)."""
    L = sh["length"]
    circle = sh["section"] == "circle"
    own, other = (("diameter", "inner_diameter"), ("width", "height")) if circle else \
        (("width", "height"), ("diameter", "inner_diameter"))
    steps = sorted(enumerate(sh["step"]), key=lambda it: it[1]["start"])
    for i, st in steps:
        key = f"shaft.step.{i}"
        if not 0.0 <= st["start"] < L:
            raise SceneError(f"{key}.start", f"x={st['start']} lies outside the shaft [0, {L})")
        if not st["start"] < st["end"]:
            raise SceneError(f"{key}.end", f"must exceed start ({st['start']}), got {st['end']}")
        if not st["end"] <= L:
            raise SceneError(f"{key}.end", f"x={st['end']} lies beyond the shaft's end ({L})")
        given = next((k for k in other if st[k] is not None), None)
        if given:
            raise SceneError(f"{key}.{given}", f"the shaft's section is a {sh['section']}, whose steps take "
                             f"{' and '.join(own)}, not {given}")
    for (i, a), (j, c) in zip(steps, steps[1:]):
        if c["start"] < a["end"]:
            raise SceneError(f"shaft.step.{j}.start", f"step {j} [{c['start']}, {c['end']}] overlaps step {i} "
                             f"[{a['start']}, {a['end']}]")
    base_mat = dict(E=sh["E"], rho=sh["rho"], G=shear_modulus(sh["E"], sh["G"], "shaft.G"))
    pieces, cursor = [], 0.0
    for i, st in steps:
        if st["start"] > cursor:
            pieces.append((cursor, st["start"], section(sh, "shaft"), base_mat))
        table = {**sh, **{k: st[k] for k in own if st[k] is not None}}
        mat = {k: sh[k] if st[k] is None else st[k] for k in ("E", "rho")}
        G = st["G"] if st["G"] is not None else (sh["G"] if st["E"] is None else None)
        mat["G"] = shear_modulus(mat["E"], G, f"shaft.step.{i}.G")
        pieces.append((st["start"], st["end"], section(table, f"shaft.step.{i}"), mat))
        cursor = st["end"]
    if cursor < L:
        pieces.append((cursor, L, section(sh, "shaft"), base_mat))
    return pieces


def shear_modulus(E: float, G: float | None, key: str) -> float | None:
    """G as given (None: the segment's default E / (2 (1 + 0.3))), checked against E: Poisson's ratio
    E / (2 G) - 1 within [0, 0.5], where the sections' shear coefficients hold."""
    if G is not None and not 0.0 <= E / (2.0 * G) - 1.0 <= 0.5:
        raise SceneError(key, f"G = {G:g} Pa with E = {E:g} Pa gives Poisson's ratio E / (2 G) - 1 = "
                         f"{E / (2.0 * G) - 1.0:.4g}, outside [0, 0.5] where the shear coefficients hold "
                         "(G from E / 3 to E / 2)")
    return G


def stepped_stack(tree: dict) -> BeamStack:
    """The stepped shaft of ``[[shaft.step]]``: one segment per piece of constant section (:func:`shaft_steps`),
    each joined rigidly to the next at the step (a junction), the ends held as ``supports`` says."""
    sh = tree["shaft"]
    if tree["delamination"]:
        raise SceneError("shaft.step", "a stepped shaft cannot carry a delamination (a delamination splits one "
                         "rectangular section into two layers); leave out one or the other")
    segments = tuple(Segment(f"intact_{k}", a, c, offset=(0.0, 0.0), **sec, **mat)
                     for k, (a, c, sec, mat) in enumerate(shaft_steps(sh)))
    junctions = tuple(Junction(s.end, s.name, (t.name,)) for s, t in zip(segments, segments[1:]))
    L = sh["length"]
    at0, atL = SUPPORT_DOFS_BY_NAME[sh["supports"]]
    supports = tuple(s for s in (Support(segments[0].name, 0.0, at0) if at0 else None,
                                 Support(segments[-1].name, L, atL) if atL else None) if s)
    contacts = []
    for i, o in enumerate(tree["obstacle"]):
        x = L if o["x"] is None else o["x"]
        if not 0.0 <= x <= L:
            raise SceneError(f"obstacle.{i}.x", f"x={x} lies outside the shaft [0, {L}]")
        seg = next(s for s in segments if s.start <= x <= s.end)
        contacts.append(Contact("obstacle", x, (seg.name,), "dirac", None, o["normal"], o["clearance"],
                                o["friction"], o["friction_directions"], o["restitution"], label=f"obstacle.{i}"))
    return BeamStack(segments, junctions, supports, tuple(contacts), tree["beam"]["theory"],
                     shear_coefficient=tree["beam"]["shear_coefficient"])


def high_level_stack(tree: dict) -> BeamStack:
    """Translate ``[shaft]``, ``[[delamination]]``, ``[[obstacle]]`` into a BeamStack (checked first)."""
    sh = tree["shaft"]
    if sh["step"]:
        return stepped_stack(tree)
    L = sh["length"]
    sec = section(sh, "shaft")
    b, h = sec["width"], sec["height"]
    mat = dict(E=sh["E"], rho=sh["rho"], G=shear_modulus(sh["E"], sh["G"], "shaft.G"))
    if tree["delamination"] and sh["section"] != "rectangle":
        raise SceneError("delamination.0", "a delamination splits a rectangular section into two layers; "
                         "use shaft.section = \"rectangle\"")
    dels = sorted(enumerate(tree["delamination"]), key=lambda it: it[1]["start"])
    for i, d in dels:
        key = f"delamination.{i}"
        if not 0.0 <= d["start"] < d["end"] <= L:
            if d["start"] >= d["end"]:
                if d["start"] >= L:   # the start moved past the shaft's end
                    raise SceneError(f"{key}.start", f"x={d['start']} lies outside the shaft [0, {L}]")
                raise SceneError(f"{key}.end", f"must exceed start ({d['start']}), got {d['end']}")
            raise SceneError(f"{key}.start" if not 0.0 <= d["start"] < L else f"{key}.end",
                             f"[{d['start']}, {d['end']}] lies outside the shaft [0, {L}]")
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
    return BeamStack(tuple(segments), tuple(junctions), tuple(supports), tuple(contacts), tree["beam"]["theory"],
                     shear_coefficient=tree["beam"]["shear_coefficient"])


def low_level_stack(tree: dict) -> BeamStack:
    """Build a BeamStack from ``[[segment]]``, ``[[junction]]``, ``[[support]]``, ``[[contact]]``."""
    segs = tuple(Segment(s["name"] or f"segment_{i}", s["start"], s["end"], offset=tuple(s["offset"]), E=s["E"],
                         rho=s["rho"], G=shear_modulus(s["E"], s["G"], f"segment.{i}.G"),
                         **section(s, f"segment.{i}")) for i, s in enumerate(tree["segment"]))
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
    return BeamStack(segs, juns, sups, tuple(cons), tree["beam"]["theory"],
                     shear_coefficient=tree["beam"]["shear_coefficient"])


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
    id_ = ip / 2.0 + m * w * w / 12.0
    if not all(math.isfinite(v) and v > 0.0 for v in (m, ip, id_)):
        # the geometry key farthest from 1 in orders of magnitude is the one that over- or underflowed
        sizes = {"outer_diameter": D, "width": w, "rho": d["rho"]}
        name = max(sizes, key=lambda k: abs(math.log10(sizes[k])))
        raise SceneError(f"{key}.{name}", f"{sizes[name]:g} gives the disk a mass {m:.3g} kg and inertias {ip:.3g}, "
                         f"{id_:.3g} kg m^2, beyond double precision")
    return m, ip, id_


BEARING_COEFFICIENTS = ("kyy", "kyz", "kzy", "kzz", "cyy", "cyz", "czy", "czz", "kxx")


def bearing(b: dict, key: str) -> Bearing:
    """A ``[[bearing]]`` table as a :class:`Bearing`: constant coefficients, or a table over ``speeds_hz`` whose
    list-valued coefficients have one value per speed (numbers stay constant); checked: lists need the speeds,
    and as many values."""
    speeds = b["speeds_hz"]
    listed = [k for k in BEARING_COEFFICIENTS if isinstance(b[k], list)]
    if listed and not speeds:
        raise SceneError(f"{key}.{listed[0]}", f"a list of coefficients needs the bearing's speeds_hz (one value per "
                         f"speed), got {b[listed[0]]}")
    if speeds and not listed:
        raise SceneError(f"{key}.speeds_hz", "a speed table needs at least one coefficient given as a list (one "
                         "value per speed)")
    for k in listed:
        if len(b[k]) != len(speeds):
            raise SceneError(f"{key}.{k}", f"has {len(b[k])} values for the {len(speeds)} speeds of speeds_hz")
    at0 = {k: b[k][0] if isinstance(b[k], list) else b[k] for k in BEARING_COEFFICIENTS}
    table = (tuple(speeds), tuple((k, tuple(b[k])) for k in listed)) if listed else ()
    out = Bearing(b["x"], ((at0["kyy"], at0["kyz"]), (at0["kzy"], at0["kzz"])),
                  ((at0["cyy"], at0["cyz"]), (at0["czy"], at0["czz"])), at0["kxx"], label=key, table=table)
    return out


def point_components(tree: dict, stack: BeamStack) -> BeamStack:
    """``stack`` with the scene's ``[[disk]]``, ``[[bearing]]`` and ``[[unbalance]]`` on it."""
    from dataclasses import replace

    lo, hi = min(s.start for s in stack.segments), max(s.end for s in stack.segments)
    middle = float(f"{(lo + hi) / 2:.12g}")
    disks = tuple(Disk(middle if d["x"] is None else d["x"], *disk_inertia(d, f"disk.{i}"), label=f"disk.{i}",
                       **({"outer_diameter": d["outer_diameter"], "inner_diameter": d["inner_diameter"],
                           "width": d["width"]} if d["mass"] is None else {}))
                  for i, d in enumerate(tree["disk"]))
    speed = tree["rotation"]["speed_hz"]
    try:
        bearings = tuple(bearing(b, f"bearing.{i}").at_speed(speed) for i, b in enumerate(tree["bearing"]))
    except SceneError as exc:
        if "outside the bearing's table" not in exc.reason:
            raise
        raise SceneError(exc.key, f"{exc.reason}: rotation.speed_hz must lie in every bearing's table") from None
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
            inside = next(((k, d) for k, d in enumerate(tree["delamination"]) if d["start"] < x < d["end"]), None)
            if inside is not None:
                k, d = inside
                raise SceneError(f"{key}.x", f"x={x} lies inside delamination.{k} [{d['start']}, {d['end']}], whose "
                                 "two layers have no single shaft surface for the ring to touch; put the stator on "
                                 "the intact shaft")
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
                               stiffness=st["stiffness"], damping=st["damping"],
                               round=st["shape"] == "round" and st["stiffness"] == 0.0))
    return tuple(out)
