"""Notes on a scene: one line for each default that shapes its model without the scene saying so, and for
keys that read differently in other programs' axes. Collected at load (``Scene.notes``); the command line
prints each once as ``nsfem <command>: note: ...`` and adds them to its JSON as ``notes``.

A scene that states what it means gets none (the shipped scenes):

>>> from nsfem.scene import load_scene
>>> load_scene("ross_example").notes
()
>>> for n in load_scene(None, ["rotation.speed_hz=0", "beam.theory=euler-bernoulli", "bearing.0.kxx=1e6",
...                            "bearing.0.kyy=1e6"]).notes:
...     print(n)
bearing.0: kxx = 1e+06 N/m with kyy and no kzz: x is the shaft axis: kxx is an axial (thrust) stiffness; the lateral directions are y (horizontal) and z (vertical, up)
"""

from __future__ import annotations

from ..stack import BeamStack
from .schema import _SECTION, AXES, LOW_LEVEL
from .validate import section_of

#: The keys that give a section's shape or size.
SECTION_KEYS = tuple(_SECTION)
#: The tables that make a scene a rotor's (the paper's beam stacks, delaminations and stops, have none).
ROTOR_TABLES = ("bearing", "disk", "unbalance", "stator", "crack")


def section_notes(raw: dict) -> list[str]:
    """A rotor's shaft (or segment) whose section the scene leaves out entirely is the default square (the
    paper's section: no note for its delaminated beams)."""
    if not any(raw.get(t) for t in ROTOR_TABLES):
        return []
    segments = raw.get("segment") or []
    segments = [segments] if isinstance(segments, dict) else segments   # one [segment] table: validated as a list
    tables = ([(f"segment.{i}", t) for i, t in enumerate(segments)] if any(t in raw for t in LOW_LEVEL) else
              [("shaft", raw.get("shaft", {}))])
    w, h = _SECTION["width"].default, _SECTION["height"].default
    out = []
    for key, t in tables:
        if not isinstance(t, dict):
            continue
        if not any(k in t for k in SECTION_KEYS):
            out.append(f"{key}: no section given: the default rectangle, {w:g} m (y) x {h:g} m (z); a round shaft "
                       f"is section = \"circle\" with its diameter")
            continue
        # a section given in part: the dimensions it uses and the table leaves out are defaults too
        uses = ("diameter",) if section_of(t) == "circle" else ("width", "height")
        missing = [k for k in uses if k not in t]
        if missing:
            out.append(f"{key}: {section_of(t)} section without {' and '.join(missing)}: the default "
                       f"{', '.join(f'{k} = {_SECTION[k].default:g} m' for k in missing)}")
    return out


def beam_notes(raw: dict) -> list[str]:
    """A rotor whose beam theory the scene leaves out gets Euler-Bernoulli's: a shaft without rotary inertia and
    without gyroscopic moments of its own (ROSS's shaft elements carry both)."""
    beam = raw.get("beam")
    if not any(raw.get(t) for t in ROTOR_TABLES) or (isinstance(beam, dict) and "theory" in beam):
        return []
    return ["beam.theory: euler-bernoulli by default: the shaft has no rotary inertia and no gyroscopic moments of "
            "its own (its disks keep theirs); theory = \"rayleigh\" adds them, \"timoshenko\" (ROSS's default) "
            "adds shear deformation too"]


#: A span (between the places that hold the shaft, or the whole shaft) shorter than this many section depths
#: is stubby: shear deformation moves its frequencies by a percent or more
STUBBY = 10.0


def shear_notes(stack: BeamStack) -> list[str]:
    """A stubby span (length below :data:`STUBBY` times its deepest section) of a model without shear
    (euler-bernoulli, rayleigh): its frequencies are too high by the shear deformation left out. The spans run
    between the bearings and the supports that hold V or W (with fewer than two, the whole shaft)."""
    if stack.theory == "timoshenko":
        return []
    lo, hi = min(s.start for s in stack.segments), max(s.end for s in stack.segments)
    held = sorted({b.x for b in stack.bearings if any(any(r) for r in b.K)}
                  | {p.x for p in stack.supports if set(p.fix) & {"V", "W"}})
    ends = list(zip(held, held[1:])) if len(held) > 1 else [(lo, hi)]
    out = []
    for a, b in ends:
        depth = max((max(s.width, s.height) for s in stack.segments if s.start < b and s.end > a), default=0.0)
        if b > a and depth > 0 and (b - a) / depth < STUBBY:
            what = f"the span x = {a:g} to {b:g} m" if len(held) > 1 else "the shaft"
            out.append(f"beam.theory: {stack.theory} on a stubby rotor: {what} is {(b - a) / depth:.3g} section "
                       f"depths long (< {STUBBY:g}); shear deformation is left out (frequencies too high); "
                       "theory = \"timoshenko\" adds it")
            break
    return out


def disk_notes(tree: dict) -> list[str]:
    """A disk given by its mass without its inertias is a point mass: no gyroscopic moment, no rotary inertia."""
    out = []
    for i, d in enumerate(tree["disk"]):
        if d["mass"] is None:   # from its geometry: every inertia computed
            continue
        missing = [k for k in ("polar_inertia", "diametral_inertia") if d[k] is None]
        if not missing:
            continue
        what = {"polar_inertia": "no gyroscopic moment", "diametral_inertia": "no rotary inertia"}
        out.append(f"disk.{i}: given by its mass, its {' and '.join(missing)} {'are' if len(missing) > 1 else 'is'} "
                   f"0 ({', '.join(what[k] for k in missing)}); give {' and '.join(missing)} in kg m^2, or the "
                   "disk's outer_diameter and width instead of its mass")
    return out


def bearing_notes(tree: dict) -> list[str]:
    """A bearing with an axial stiffness beside lateral ones that reads like another program's axes: kxx with
    kyy and no kzz (ROSS's horizontal and vertical), or kxx as large as the smaller lateral stiffness."""
    out = []
    for i, b in enumerate(tree["bearing"]):
        kxx, kyy, kzz = (max(b[k]) if isinstance(b[k], list) else b[k] for k in ("kxx", "kyy", "kzz"))
        lateral = [k for k in (kyy, kzz) if k > 0.0]
        if not (kxx > 0.0 and lateral):
            continue   # no axial stiffness, or a thrust bearing alone: nothing to misread
        if kyy and not kzz:
            why = "with kyy and no kzz"
        elif kxx >= min(lateral):
            why = f"as large as its lateral {'kyy' if min(lateral) == kyy else 'kzz'} = {min(lateral):g} N/m"
        else:
            continue
        out.append(f"bearing.{i}: kxx = {kxx:g} N/m {why}: {AXES}")
    return out


def scene_notes(raw: dict, tree: dict, stack: BeamStack) -> tuple[str, ...]:
    """The notes on a scene: ``raw`` as its file and overrides give it, ``tree`` validated with every default,
    ``stack`` its translation. Rigid motions that nothing restrains are not notes: the model says them exactly
    (:func:`nsfem.analysis.rigid_motion.free_motions`), once, where they matter (run, modes, stationary)."""
    return tuple(section_notes(raw) + beam_notes(raw) + shear_notes(stack) + disk_notes(tree) + bearing_notes(tree))
